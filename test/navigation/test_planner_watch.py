"""The navigator's watch on the planner's refusals of its twists."""

from __future__ import annotations

import json

import pytest

from crawler_motion.errors import CommandError
from crawler_motion.model.config import load_config
from crawler_motion.motion.gait import WalkParams
from crawler_motion.navigation.navigator import NavigatorSettings, NavState, VirtualBodyNavigator
from crawler_motion.navigation.planner_watch import RefusalWatch
from crawler_motion.planner.commands import twist_to_params

CFG = load_config()


def status(refusals: int, last: str | None) -> str:
    return json.dumps({"state": "STANDING", "refusals": refusals, "last_refusal": last})


def refusal_of(vx: float, wz: float = 0.0, gait: str = "diagonal_sway") -> str:
    """The planner's own text for a twist (raised by the one conversion it uses)."""
    try:
        twist_to_params(vx, 0.0, wz, CFG, WalkParams.defaults(CFG.gait, gait=gait))
    except CommandError as exc:
        return str(exc)
    raise AssertionError("the twist was accepted")


@pytest.mark.parametrize(("texts", "fails"), [
    ([status(2, None), status(3, refusal_of(0.08))], True),  # diagonal_sway: max 0.055 m/s
    ([status(3, refusal_of(0.01, 0.5))], True),  # yaw rate
    ([status(2, refusal_of(0.08))], False),  # the refusal before the goal, seen again
    ([status(3, "cmd_vel ignored in state STOPPING: wait for STANDING")],
     False),  # a stop in progress: the next twist may be taken
    ([status(3, "cmd_vel ignored in state IDLE: send stand first")], True),  # never stood
    ([status(3, "cmd_vel ignored in state SITTING: send stand first")], True),
    ([status(3, "walk refused in state IDLE: send stand first")], False),  # not a twist
    ([status(3, "cmd_vel ignored in state ESTOP: send stand first")], True),
    ([status(3, "cmd_vel ignored in state HOLDING: send stand first")], True),  # held
    ([status(3, "cmd_vel ignored in state HOLDING: wait for the resume from the measured "
                "pose")], False),  # an interruption: it resumes by itself
    ([status(3, "cmd_vel ignored: the body is posed (x 0.01 m); walks start from the neutral "
                "pose: send stand first")], True),
    ([status(3, "paused: motor manager fault")], False),
    (["not json", "[]", json.dumps({"refusals": "x"}), json.dumps({"refusals": 9})], False),
])
def test_a_twist_beyond_the_walk_ends_the_goal_other_refusals_do_not(texts, fails):
    watch = RefusalWatch()
    watch.update(status(2, refusal_of(0.08)))  # the count before the goal
    watch.start()
    reasons = [watch.update(t) for t in texts]
    found = [r for r in reasons if r is not None]
    assert bool(found) is fails
    if fails:
        assert found[0].startswith("the planner refuses the navigator's twists: cmd_vel")


def test_the_same_refusal_ends_a_goal_once():
    watch = RefusalWatch()
    watch.update(status(0, None))
    watch.start()
    assert watch.update(status(1, refusal_of(0.08))) is not None
    assert watch.update(status(1, refusal_of(0.08))) is None  # the same status again


def test_fail_ends_an_active_goal_only():
    nav = VirtualBodyNavigator(NavigatorSettings())
    assert nav.fail("x") is False and nav.state is NavState.IDLE
    nav.set_goal(1.0, 0.0, 0.0)
    assert nav.fail("the planner refuses") is True
    assert nav.state is NavState.FAILED and nav.reason == "the planner refuses"


def test_the_navigator_node_fails_its_goal_when_the_planner_refuses_its_twists():
    """In-process: a goal, then the planner's status refusing a twist beyond its limits."""
    import threading

    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import String

    from crawler_motion.navigation.node import NavigatorNode
    from crawler_motion.testing.polling import wait_until

    context = Context()
    rclpy.init(context=context)
    nav = NavigatorNode(context=context)
    probe = rclpy.create_node("navigation_probe", context=context)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    statuses: list[dict] = []
    planner = probe.create_publisher(String, "planner_status", latched)
    goal = probe.create_publisher(PoseStamped, "goal_pose", 10)
    probe.create_subscription(String, "navigation_status",
                              lambda m: statuses.append(json.loads(m.data)), latched)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(nav)
    executor.add_node(probe)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    try:
        planner.publish(String(data=status(0, None)))
        msg = PoseStamped()
        msg.header.frame_id, msg.pose.position.x = "odom", 1.0
        assert wait_until(lambda: goal.get_subscription_count() > 0, 5.0)
        goal.publish(msg)
        assert wait_until(lambda: statuses and statuses[-1]["state"] == "ACTIVE", 5.0)
        planner.publish(String(data=status(1, refusal_of(0.08))))
        assert wait_until(lambda: statuses[-1]["state"] == "FAILED", 5.0), statuses[-1]
        assert "exceeds the maximum" in statuses[-1]["reason"]
    finally:
        executor.shutdown(timeout_sec=2.0)
        nav.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)


def test_the_first_status_heard_is_the_baseline_not_news():
    # a restarted navigator hears the planner's latched status: its refusal is minutes old
    watch = RefusalWatch()
    watch.start()
    assert watch.update(status(7, "cmd_vel ignored in state IDLE: send stand first")) is None
    assert watch.update(status(8, "cmd_vel ignored in state IDLE: send stand first")) \
        is not None  # a new one after it is


def test_a_refused_twist_the_navigator_did_not_send_is_not_blamed_on_it():
    from crawler_motion.navigation.guards import SentTwists

    sent = SentTwists()
    sent.add((0.04, 0.0, 0.0))
    watch = RefusalWatch()
    watch.update(status(0, None))
    watch.start()
    foreign = json.loads(status(1, refusal_of(1e6)))
    foreign["refused_twist"] = [1e6, 0.0, 0.0]  # another node's twist
    assert watch.update(json.dumps(foreign), sent) is None
    assert watch.foreign == 1 and "another publisher" in watch.last_foreign
    own = json.loads(status(2, refusal_of(0.08)))
    own["refused_twist"] = [0.08, 0.0, 0.0]
    sent.add((0.08, 0.0, 0.0))
    assert watch.update(json.dumps(own), sent).startswith("the planner refuses the navigator")
