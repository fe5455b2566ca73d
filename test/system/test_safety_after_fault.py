"""After a fault: what moves next, and from where (one end-to-end test per item of the safety
issue), on a cross-process bus with the simulated manager in this process.

Each test prints what it measured (``pytest -s``) and repeats it in its assertion messages.
The stack, tap and console are those of ``test_fault_injection.py`` (loaded from its file).
"""

from __future__ import annotations

import importlib.util
import json
import os
import signal
import socket
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from sensor_msgs.msg import JointState  # noqa: E402

from crawler_motion.tools.recover import DriverState, recover  # noqa: E402

_spec = importlib.util.spec_from_file_location(
    "fault_injection_stack", Path(__file__).with_name("test_fault_injection.py"))
assert _spec is not None and _spec.loader is not None
fi = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fi)
PROTOCOL, STAND, WAIT = fi.PROTOCOL, fi.STAND, fi.WAIT
JOINTS = list(PROTOCOL.joint_names)
#: A resume's first target lies at most this far from the measured pose [rad]: one tick of the
#: resume move plus the measurement's lag.
RESUME_TOLERANCE = 0.05


make_stack = fi.make_stack  # the fixture of test_fault_injection.py


def _report(text: str) -> str:
    print(f"\n[safety] {text}")
    return text


def _measured_before(stack: Any, t: float) -> np.ndarray:
    return [q for ts, q in stack.states if ts <= t][-1]


def _first_command_after(stack: Any, t: float) -> tuple[float, np.ndarray]:
    assert stack.wait(lambda: any(ts > t for ts, _ in stack.commands), 5.0), "no command"
    return next((ts, q) for ts, q in stack.commands if ts > t)


def _freeze(stack: Any, name: str, seconds: float) -> float:
    """SIGSTOP ``name`` for ``seconds``; returns the time of the SIGCONT."""
    pid = stack.processes.pids()[name]
    os.kill(pid, signal.SIGSTOP)
    time.sleep(seconds)
    os.kill(pid, signal.SIGCONT)
    return time.monotonic()


def _state(stack: Any, state: str, after: float) -> float | None:
    return fi._first(stack.statuses, after, lambda s: s["state"] == state)


# ---- 1. a resume jumps ---------------------------------------------------------------------


def test_1_a_frozen_planner_resumes_from_the_measured_pose(make_stack):
    """SIGSTOP of the planner (below both command timeouts): the first target after it lies
    within one resume step of the measured pose, not 0.6 s ahead on the open-loop plan."""
    stack = make_stack(command_timeout=2.0, sim_timeout=1.5)
    stack.up_and_walking()
    stack.spin(0.6)
    t_cont = _freeze(stack, "planner_node", 0.6)  # 1.5 slots: not a whole gait cycle
    t_first, first = _first_command_after(stack, t_cont)
    measured = _measured_before(stack, t_cont)
    jump = float(np.abs(first - measured).max())
    stack.spin(2.5)
    text = _report(f"planner frozen 0.6 s: first target {jump:.3f} rad from the measured pose "
                   f"({(t_first - t_cont) * 1e3:.0f} ms after SIGCONT); state "
                   f"{stack.status.get('state')}")
    assert jump <= RESUME_TOLERANCE, text
    assert stack.status["state"] == "WALKING" and not stack.status["resuming"], text


# ---- 2. a walk restarts by itself ------------------------------------------------------------


#: The pipelines of the tests that also run the composed controller (`controller_node`).
PIPELINES = pytest.mark.parametrize("controller", [False, True], ids=["two-node", "controller"])


@PIPELINES
def test_2_a_driver_estop_ends_the_walk_reset_and_enable_do_not_resume_it(make_stack,
                                                                          controller):
    stack = make_stack(controller=controller)
    stack.up_and_walking()
    stack.spin(0.5)
    t0 = time.monotonic()
    stack.trigger("estop")
    assert stack.wait(lambda: stack.status.get("state") == "IDLE"), stack.status
    t_idle = _state(stack, "IDLE", t0)
    stack.trigger("reset")
    stack.trigger("enable")
    t_enable = time.monotonic()
    stack.spin(1.5)
    text = _report(f"driver ~/estop mid-walk -> planner IDLE {(t_idle - t0) * 1e3:.0f} ms; "
                   f"after reset + enable: {len(stack.tap.of('target', t_enable))} target "
                   f"frames in 1.5 s, state {stack.status.get('state')}")
    assert stack.status["state"] == "IDLE", text
    assert stack.tap.of("target", t_enable) == [], text
    assert not [c for c in stack.commands if c[0] > t_enable], text


# ---- 3. the driver sends any step it is given ------------------------------------------------


@PIPELINES
def test_3_a_1_rad_step_is_refused_and_a_second_publisher_is_an_error(make_stack, controller):
    stack = make_stack(controller=controller)
    stack.up_and_walking()
    stack.spin(0.5)
    last = stack.commands[-1][1].copy()
    knee = JOINTS.index("lf_knee_joint")
    last[knee] = last[knee] + 1.0 if last[knee] + 1.0 < PROTOCOL.upper[knee] else last[knee] - 1.0
    pub = stack.console.node.create_publisher(JointState, "joint_commands", 1)
    assert stack.wait(lambda: pub.get_subscription_count() > 0, 5.0)
    t0 = time.monotonic()
    msg = JointState(name=JOINTS, position=last.tolist())

    def racing() -> bool:
        """The second publisher races the planner: one more message per call (the driver's
        best-effort, depth-1 reader may drop one taken over by the planner's next)."""
        pub.publish(msg)
        return "more than one publisher" in (stack.diag() or (0, ""))[1]

    assert stack.wait(racing, 5.0), stack.diag()
    t_err = fi._first(stack.diagnostics, t0, lambda e: "more than one publisher"
                      in e.get("motor manager", (0, ""))[1])
    stack.spin(1.5)
    wild = [f for _, f in stack.tap.of("target", t0)
            if abs(f.positions.get("lf_knee_joint", np.inf) - last[knee]) < 0.01]
    values = stack.diag()[2]
    text = _report(f"1 rad step from a second publisher: {len(wild)} such target frames on the "
                   f"bus; step_refused {values['step_refused']}; ERROR 'more than one "
                   f"publisher' after {(t_err - t0) * 1e3:.0f} ms; planner "
                   f"{stack.status.get('state')}")
    assert wild == [], text
    assert int(values["step_refused"]) >= 1 and int(values["sender_conflicts"]) >= 1, text


# ---- 4. a hold the driver did not send ---------------------------------------------------------


def test_4_a_spoofed_hold_is_an_error_that_pauses_and_enable_resumes_smoothly(make_stack):
    stack = make_stack()
    stack.up_and_walking()
    stack.spin(0.5)
    t0 = time.monotonic()
    stack.listener.bus.send(PROTOCOL.encode_control("hold"))
    assert stack.wait(lambda: stack.status.get("paused")), stack.status
    t_err = fi._first(stack.diagnostics, t0, lambda e: "did not command"
                      in e.get("motor manager", (0, ""))[1] or "foreign"
                      in e.get("motor manager", (0, ""))[1])
    t_pause = fi._first(stack.statuses, t0, lambda s: s["paused"])
    step = stack.status["step"]
    stack.spin(1.5)
    assert stack.status["step"] == step and stack.sim.state == "hold", stack.status
    t_enable = time.monotonic()
    stack.trigger("enable")
    assert stack.wait(lambda: stack.status.get("step", 0) > step), stack.status
    # what moves: the first target frames on the bus after the enable, against the pose the
    # manager held (it held still since the spoofed hold)
    held = _measured_before(stack, t_enable)
    # until the enable frame the manager ignores targets (in hold): count from that frame on
    t_frame = next(t for t, c in stack.tap.controls(t_enable) if c == "enable")
    frames = stack.tap.of("target", t_frame)[:4]
    jump = max(abs(v - held[JOINTS.index(n)]) for _, f in frames for n, v in f.positions.items())
    text = _report(f"spoofed MM_Control hold -> driver ERROR {(t_err - t0) * 1e3:.0f} ms, "
                   f"planner paused {(t_pause - t0) * 1e3:.0f} ms; after ~/enable the first "
                   f"target on the bus is {jump:.3f} rad from the measured pose; the walk goes "
                   f"on")
    assert frames and jump <= RESUME_TOLERANCE, text


# ---- 5. a malformed datagram -----------------------------------------------------------------


def test_5_a_malformed_datagram_is_a_bad_frame_not_a_bus_failure(make_stack):
    stack = make_stack()
    stack.up_and_walking()
    stack.spin(0.3)
    target = (stack.bus_spec.channel, stack.bus_spec.port)  # the multicast group and port
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
    t0 = time.monotonic()
    for _ in range(5):
        sock.sendto(b"\x93not a can message", target)
        stack.spin(0.2)
    sock.close()
    stack.spin(0.5)
    values = stack.diag("CAN bus")[2]
    text = _report(f"5 malformed datagrams during a walk: rx_malformed {values['rx_malformed']}, "
                   f"bus_failures {values['bus_failures']}, reopens {values['reopens']}; "
                   f"planner {stack.status.get('state')}")
    assert int(values["rx_malformed"]) >= 5 and int(values["bus_failures"]) == 0, text
    assert stack.status["state"] == "WALKING" and t0 > 0, text


# ---- 6. the operator recovers with the package's tools -------------------------------------


def _recover_then_stand(stack: Any, what: str) -> str:
    driver = DriverState(stack.console)
    lines: list[str] = []
    ok, message = recover(stack.console, driver, lines.append)
    assert ok, f"{what}: recover refused: {message} ({lines})"
    ok, stand = stack.console.run_when_ready({"command": "stand"}, WAIT)
    assert ok, f"{what}: stand after recover: {stand}"
    return "; ".join(lines)


def test_6_console_recover_then_stand_after_an_estop_and_after_a_watchdog_trip(make_stack):
    stack = make_stack()
    stack.up_and_walking()
    stack.console.send({"command": "estop"})
    assert stack.wait(lambda: stack.status.get("state") == "ESTOP")
    assert stack.wait(lambda: stack.sim.state == "estop")
    steps = _recover_then_stand(stack, "e-stop")
    stack.run({"command": "walk", "swing_time": fi.SWING})
    # 3 x command_timeout: the watchdog trips even when a loaded machine delivers the last
    # commands before the freeze late
    _freeze(stack, "planner_node", 3.0)
    assert stack.wait(lambda: stack.status.get("state") == "IDLE"), stack.status
    trip = _recover_then_stand(stack, "watchdog trip")
    _report(f"recover after e-stop: {steps}; after a watchdog trip: {trip}; stand works")


def test_6_recover_refuses_while_the_cause_persists(make_stack):
    """An axis fault that stays: the reset leaves the manager in ``fault`` and recover says so;
    once the fault is gone, recover and stand work."""
    stack = make_stack()
    stack.up_and_walking()
    stack.sim.inject_axis_fault(4)
    assert stack.wait(lambda: stack.sim.state == "fault")
    assert stack.wait(lambda: (stack.diag() or {2: {}})[2].get("manager_state") == "fault")
    driver = DriverState(stack.console)
    lines: list[str] = []
    ok, message = recover(stack.console, driver, lines.append, timeout=1.5)
    _report(f"recover with an axis fault present: {message} ({'; '.join(lines)})")
    assert not ok and "still in fault" in message, (message, lines)
    stack.sim.clear_faults()
    ok, message = recover(stack.console, driver, lines.append)
    assert ok, message
    # a manager fault paused the walk (it did not end it): it resumes from the measured pose
    assert stack.wait(lambda: stack.status.get("state") == "WALKING"
                      and not stack.status.get("paused") and not stack.status.get("resuming"))
    stack.run({"command": "stop"})


def test_smaller_status_carries_driver_state(make_stack):
    stack = make_stack()
    stack.up_and_walking()
    assert stack.wait(lambda: stack.status.get("driver") == "enabled"), stack.status
    status = json.loads(json.dumps(stack.status))
    assert status["resuming"] is False


# ---- 7. smaller: every node exits 0 on SIGINT / SIGTERM in any state --------------------------


def test_7_every_node_exits_0_when_interrupted_mid_walk_again_and_again(make_stack):
    """Planner and driver, each interrupted three times (SIGINT, SIGTERM, SIGINT) while the
    robot walks (commands, statuses and feedback flowing), restarted, recovered and walking
    again: every exit status is 0."""
    stack = make_stack()
    stack.up_and_walking()
    driver = DriverState(stack.console)
    exits = []
    for i, sig in enumerate((signal.SIGINT, signal.SIGTERM, signal.SIGINT)):
        for name in ("planner_node", "driver_node"):
            stack.spin(0.3 + 0.07 * i)  # mid-walk, at a different phase each time
            assert stack.console.wait_until(lambda: driver.status is not None, WAIT)
            instance = driver.status["instance"]
            proc = stack.procs[name]
            proc.send_signal(sig)
            code = proc.wait(15)
            exits.append((name, sig.name, code))
            assert code == 0, f"{name} exited {code} on {sig.name}:\n{stack.log_tails(30)}"
            stack.processes.start({name: stack.spec.commands()[name]}, fi.isolated_env())
            stack.statuses.clear()
            if name == "driver_node":  # the new driver up (a loaded machine: seconds)
                assert stack.console.wait_until(
                    lambda old=instance: driver.status["instance"] != old, WAIT), (
                    f"the driver did not come back\n{stack.log_tails(30)}")
            assert stack.console.wait_until(  # the planner up and hearing the driver
                lambda: stack.status.get("driver") is not None, WAIT), (
                f"{name} did not come back: {stack.status}")
            assert stack.console.wait_until(  # a restarted driver ends the walk (never resumes)
                lambda: stack.status.get("state") not in ("WALKING", "STOPPING"), WAIT), (
                f"the walk went on after {name} restarted: {stack.status}")
            _recover_then_stand(stack, f"after {name} {sig.name}")
            stack.run({"command": "walk", "swing_time": fi.SWING})
    _report(f"interrupted mid-walk: {exits}")
