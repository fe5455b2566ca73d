"""What holds the navigator: the map's content age, other cmd_vel publishers, twists it sent."""

from __future__ import annotations

import math

from crawler_motion.navigation.guards import (
    MapFreshness,
    SentTwists,
    foreign_publishers,
    foreign_reason,
)


def test_the_content_age_grows_while_the_stamp_of_the_last_fused_scan_stays() -> None:
    fresh = MapFreshness()
    assert math.isinf(fresh.age(5.0))
    assert "no fused scan" in (fresh.stale_reason(5.0, 1.0) or "")
    fresh.note(100.0, 100.2, 10.0)  # fused 0.2 s before it arrived
    assert abs(fresh.age(10.0) - 0.2) < 1e-9 and fresh.stale_reason(10.0, 1.0) is None
    for k in range(1, 20):  # the map keeps coming, its content does not change
        fresh.note(100.0, 100.2 + 0.1 * k, 10.0 + 0.1 * k)
    assert abs(fresh.age(11.9) - 2.1) < 1e-9
    assert "2.10 s old (map_max_age 1 s" in (fresh.stale_reason(11.9, 1.0) or "")
    fresh.note(102.0, 102.0, 12.0)  # fused again
    assert fresh.stale_reason(12.0, 1.0) is None


def test_no_content_or_a_future_stamp() -> None:
    fresh = MapFreshness()
    fresh.note(100.0, 100.0, 1.0)
    fresh.note(0.0, 101.0, 2.0)  # the mapper restarted its odometry: nothing fused
    assert math.isinf(fresh.age(2.0))
    fresh.note(200.0, 100.0, 3.0)  # ahead of the navigator's clock: age 0, then it grows
    assert fresh.age(3.0) == 0.0 and fresh.stale_reason(4.5, 1.0) is not None


def test_other_publishers_are_named_and_the_navigator_is_not() -> None:
    pubs = [("navigator", "/"), ("teleop", "/"), ("teleop", "/"), ("nav2", "/crawler1")]
    assert foreign_publishers(pubs, ("navigator", "/")) == ["/crawler1/nav2", "/teleop"]
    assert foreign_publishers([("navigator", "/r1")], ("navigator", "/r1")) == []
    assert "/teleop" in foreign_reason(["/teleop"], 1.0)
    assert "gone already" in foreign_reason([], 1.0)


def test_sent_twists_are_recognised_exactly() -> None:
    sent = SentTwists()
    sent.add((0.08, 0.0, 0.01))
    assert [0.08, 0.0, 0.01] in sent and [1e6, 0.0, 0.0] not in sent
    assert "junk" not in sent and None not in sent


def test_a_twist_heard_more_often_than_sent_is_another_nodes() -> None:
    sent = SentTwists()
    sent.add((0.0, 0.0, 0.0))
    sent.add((0.05, 0.0, 0.0))
    assert sent.echo([0.05, 0.0, 0.0]) and sent.echo([0.0, 0.0, 0.0])
    assert not sent.echo([0.0, 0.0, 0.0])  # a second zero twist: not the navigator's
    assert not sent.echo([1e6, 0.0, 0.0])
    assert [0.0, 0.0, 0.0] in sent  # still its own for attributing refusals
