"""The planner's foot contacts (pure): efforts of a joint state, the foot_contacts JSON and its
pacing, the diagnostic level, the contact parameters."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from crawler_motion.errors import CommandError
from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import foot_jacobians, inverse_kinematics
from crawler_motion.motion.contact_estimation import ContactSettings
from crawler_motion.planner.contacts import (
    GROUND_LOAD_WINDOW,
    MISSING_WARN_AFTER,
    PUBLISH_PERIOD,
    ContactMonitor,
    efforts_in_order,
)
from crawler_motion.planner.parameters import default_values, planner_parameters, planner_settings

CFG = load_config()
NAMES = list(CFG.robot.joint_names)
STAND = inverse_kinematics(CFG.robot, CFG.robot.standing_feet())


def holding(force_z: float) -> np.ndarray:
    """Joint torques (joint order [N m]) holding ``force_z`` [N] up on every standing foot."""
    force = np.zeros((4, 3))
    force[:, 2] = force_z
    return -np.einsum("lji,lj->li", foot_jacobians(CFG.robot, STAND), force).reshape(-1)


@pytest.mark.parametrize(("names", "efforts", "ok", "why"), [
    (NAMES, list(range(12)), True, ""),
    (NAMES[::-1], list(range(12))[::-1], True, ""),  # reordered by name
    (NAMES, [], False, "carry no effort"),
    (NAMES, [0.0] * 11, False, "11 efforts for 12 names"),
    (NAMES, [0.0] * 13, False, "13 efforts"),
    (NAMES, [0.0] * 11 + ["x"], False, "not a number"),
    (NAMES, [0.0] * 11 + [True], False, "not a number"),
    (NAMES, [0.0] * 11 + [math.nan], True, ""),  # a NaN leg: unknown there, not refused
])
def test_efforts_in_order(names, efforts, ok, why):
    tau, reason = efforts_in_order(names, efforts, NAMES)
    assert (tau is not None) == ok and why in reason
    if ok and not np.isnan(tau).any():
        np.testing.assert_array_equal(tau, np.arange(12.0))


def run(monitor: ContactMonitor, efforts, n: int, t0: float = 0.0) -> list[str | None]:
    return [monitor.update(NAMES, STAND, efforts, t0 + 0.01 * k, t0 + 0.01 * k)
            for k in range(n)]


def test_the_json_says_contact_and_force_per_foot():
    monitor = ContactMonitor(CFG.robot)
    texts = [t for t in run(monitor, list(holding(2.0)), 6) if t is not None]
    last = json.loads(texts[-1])
    assert last["effort"] is True and last["reason"] == ""
    assert last["stamp"] == pytest.approx(0.02)  # sample 2, known at sample 3: the change
    assert set(last["feet"]) == {"lf", "lb", "rb", "rf"}
    for foot in last["feet"].values():
        assert foot["contact"] == "yes" and foot["force"] == pytest.approx(2.0, abs=1e-3)
    assert monitor.report() == {"effort": True, "ground_load": True, "feet": last["feet"]}


def test_it_is_published_on_change_and_at_least_every_period():
    monitor = ContactMonitor(CFG.robot)
    texts = run(monitor, list(holding(2.0)), 40)
    sent = [k for k, t in enumerate(texts) if t is not None]
    assert sent[0] == 0  # the first (unknown) estimate
    assert 3 in sent  # the change to contact
    gaps = np.diff(sent[1:])
    assert gaps.max() <= round(PUBLISH_PERIOD / 0.01) and len(sent) < 10


def test_missing_efforts_are_unknown_and_warned_after_a_while():
    monitor = ContactMonitor(CFG.robot)
    assert monitor.diagnostic(0.0) == (False, "no joint_states yet")
    assert monitor.report()["feet"]["lf"] == {"contact": "unknown", "force": None}
    run(monitor, list(holding(2.0)), 5)
    assert monitor.diagnostic(0.05)[0] is False
    text = [t for t in run(monitor, [], 30, t0=0.05) if t is not None][-1]
    data = json.loads(text)
    assert data["effort"] is False and "carry no effort" in data["reason"]
    assert {f["contact"] for f in data["feet"].values()} == {"unknown"}
    assert monitor.diagnostic(0.05 + MISSING_WARN_AFTER - 0.001)[0] is False
    warn, message = monitor.diagnostic(0.05 + MISSING_WARN_AFTER)
    assert warn and "carry no effort" in message
    run(monitor, list(holding(2.0)), 5, t0=0.4)
    assert monitor.diagnostic(0.5)[0] is False  # efforts back: OK at once


def test_configure_changes_the_threshold():
    monitor = ContactMonitor(CFG.robot)
    run(monitor, list(holding(2.0)), 5)
    assert monitor.report()["feet"]["rf"]["contact"] == "yes"
    monitor.configure(ContactSettings(threshold=5.0, hysteresis=1.0))
    run(monitor, list(holding(2.0)), 2, t0=0.05)
    assert monitor.report()["feet"]["rf"]["contact"] == "no"


@pytest.mark.parametrize(("changes", "ok"), [
    ({}, True),
    ({"contact_threshold": 2.0, "contact_hysteresis": 2.0}, True),
    ({"contact_threshold": 1.0, "contact_hysteresis": 1.5}, False),  # lift-off below zero
    ({"contact_threshold": 0.0}, False),
    ({"contact_drive_inertia": 0.0}, True),
    ({"contact_drive_inertia": -0.1}, False),
    ({"contact_period": 0.005}, True),
    ({"contact_period": 0.0}, False),
])
def test_contact_parameters(changes, ok):
    specs = planner_parameters(CFG, "robot.yaml")
    values = {**default_values(specs), **changes}
    if not ok:
        with pytest.raises(CommandError, match="contact"):
            planner_settings(specs, values, CFG)
        return
    contacts = planner_settings(specs, values, CFG).contacts
    assert contacts.threshold == values["contact_threshold"]
    assert contacts.hysteresis == values["contact_hysteresis"]
    assert contacts.drive_inertia == values["contact_drive_inertia"]
    assert contacts.period == values["contact_period"]


def test_efforts_without_a_ground_load_are_said_and_leave_the_blind_plan():
    # a joint-only manager: efforts that hold no weight (every foot ~0 N)
    monitor = ContactMonitor(CFG.robot)
    texts = [t for t in run(monitor, [0.0] * 12, 20) if t is not None]
    data = json.loads(texts[-1])
    assert data["effort"] is True and data["ground_load"] is False
    assert "no ground load" in data["reason"] and monitor.ground_load is False
    # the robot put down: loaded at once; lifted again: unloaded after GROUND_LOAD_WINDOW
    run(monitor, list(holding(2.0)), 5, t0=1.0)
    assert monitor.ground_load is True
    run(monitor, [0.0] * 12, round(GROUND_LOAD_WINDOW / 0.01) - 5, t0=1.05)
    assert monitor.ground_load is True
    run(monitor, [0.0] * 12, 10, t0=1.05 + GROUND_LOAD_WINDOW - 0.05)
    assert monitor.ground_load is False


def test_the_walk_walks_blind_without_a_ground_load():
    from crawler_motion.motion.foothold import FootholdSettings
    from crawler_motion.planner.footholds import Footholds

    footholds = Footholds(CFG.robot, FootholdSettings(enabled=True))
    footholds.monitor = ContactMonitor(CFG.robot)
    run(footholds.monitor, [0.0] * 12, 20)
    assert footholds._estimate()[0] is None  # unknown: the blind plan
    run(footholds.monitor, list(holding(2.0)), 5, t0=0.2)
    assert footholds._estimate()[0] is not None
