"""The planner's foot contacts: measured joint states in, ``foot_contacts`` JSON and a diagnostic
status out (pure: no rclpy; the estimation is `motion.contact_estimation`).

``foot_contacts`` (std_msgs/String, one JSON object) is published on every change of a foot's
contact and at least every `PUBLISH_PERIOD` while joint states arrive::

    {"stamp": 12.34, "effort": true, "reason": "",
     "feet": {"lf": {"contact": "yes", "force": 3.21}, ..., "rf": {"contact": "no",
              "force": 0.02}}}

``stamp`` [s] is the time of the joint state the estimate describes (one feedback period before
the newest), ``contact`` one of ``yes``, ``no``, ``unknown``, ``force`` the estimated normal
force [N] (null when unknown), ``effort`` whether the joint states carry efforts, ``reason``
why contacts are unknown ("" when none is). The same ``feet`` and ``effort`` are the
``contacts`` of ``planner_status``. Joint states without efforts (an older manager, a driver
that cannot decode them) make every contact unknown and, after `MISSING_WARN_AFTER`, put the
planner's ``foot contacts`` status on ``/diagnostics`` at WARN.

``ground_load`` says whether the efforts carry the robot's weight: true once the feet's
estimated normal forces have added up to more than `GROUND_LOAD` within the last
`GROUND_LOAD_WINDOW`. A bus whose efforts carry no ground load (the joint-only
``motor_manager_sim``, a robot lifted off the ground) reads false with a ``reason``, and the
terrain-adaptive touch-down, the stumble retry and the attitude walk the blind plan instead of
seeing false touch-downs and hits.
"""

from __future__ import annotations

import array
import json
import math
import threading
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from crawler_motion.model.config import RobotConfig
from crawler_motion.model.joint_state import as_float
from crawler_motion.motion.contact_estimation import (
    ContactEstimate,
    ContactEstimator,
    ContactSettings,
    FootContact,
)

#: ``foot_contacts`` goes out at least this often while joint states arrive [s].
PUBLISH_PERIOD = 0.1
#: Efforts missing for this long [s] put the diagnostic status at WARN (a single incomplete
#: cycle does not).
MISSING_WARN_AFTER = 0.25
#: The diagnostic status: what it is about (its name is ``<node>: foot contacts``), hardware_id.
STATUS_WHAT = "foot contacts"
#: Sum of the feet's normal forces [N] above which the efforts carry a ground load (a standing
#: crawler in water carries ~9 N; a joint-only simulated manager reports ~0).
GROUND_LOAD = 2.0
#: The load must have been seen this recently [s] (a walk always has two feet down).
GROUND_LOAD_WINDOW = 1.0
#: The contacts' reason while the efforts carry no ground load.
NO_GROUND_LOAD = ("the joint efforts carry no ground load (a joint-only manager, or the robot "
                  "off the ground): the rough-ground features walk the blind plan")
HARDWARE_ID = "crawler_planner"


def efforts_in_order(names: Sequence[str], efforts: Sequence[Any],
                     joint_names: Sequence[str] | Mapping[str, int]
                     ) -> tuple[np.ndarray | None, str]:
    """The efforts of a joint state in ``joint_names`` order (or by a name -> index map)
    [N m] and "", or None and why they cannot be used (none sent, a wrong count, a name or
    value that is not usable). The names themselves were checked with the positions."""
    if len(efforts) == 0:
        return None, "joint_states carry no effort"
    if len(efforts) != len(names):
        return None, (f"joint_states carry {len(efforts)} efforts for {len(names)} names "
                      f"(0 or {len(names)} allowed)")
    index = joint_names if isinstance(joint_names, Mapping) else {
        name: i for i, name in enumerate(joint_names)}
    tau = np.full(len(index), np.nan)
    if isinstance(efforts, (array.array, np.ndarray)) and all(n in index for n in names):
        tau[[index[n] for n in names]] = np.asarray(efforts, dtype=float)  # rclpy: array('d')
        return tau, ""
    for name, value in zip(names, efforts, strict=True):
        number = as_float(value)
        if name not in index or number is None:
            return None, f"joint_states effort {value!r:.40} of {name!r} is not a number"
        tau[index[name]] = number
    return tau, ""


class ContactMonitor:
    """The contact estimator of the planner, its last estimate and when to publish.

    Thread-safe with a lock of its own, so that the estimate (~0.1 ms a joint state) is not
    computed under the node's lock, which the tick thread takes.
    """

    def __init__(self, robot: RobotConfig, settings: ContactSettings | None = None) -> None:
        self.robot = robot
        self.estimator = ContactEstimator(robot, settings)
        self._index = {name: i for i, name in enumerate(robot.joint_names)}
        self.last: ContactEstimate | None = None
        self.has_effort = False
        self._missing_since: float | None = None
        self._published_at = -math.inf
        self._published_states: tuple[FootContact, ...] = ()
        self._loaded_at = -math.inf  # when the feet last carried `GROUND_LOAD` [s]
        self._now = -math.inf
        self._lock = threading.Lock()

    def __getstate__(self) -> dict[str, Any]:
        """Copies (the planner core is copied to try commands) get a lock of their own."""
        state = dict(self.__dict__)
        del state["_lock"]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()

    def configure(self, settings: ContactSettings) -> None:
        """New threshold, hysteresis and drive inertia."""
        with self._lock:
            self.estimator.configure(settings)

    def update(self, names: Sequence[str], angles: np.ndarray, efforts: Sequence[Any],
               stamp: float, now: float) -> str | None:
        """Take one joint state (``angles`` in joint order [rad], ``efforts`` in ``names``
        order [N m]) stamped ``stamp`` [s], received at steady time ``now`` [s]; the
        ``foot_contacts`` JSON to publish now, or None."""
        with self._lock:
            return self._update(names, angles, efforts, stamp, now)

    def _update(self, names: Sequence[str], angles: np.ndarray, efforts: Sequence[Any],
                stamp: float, now: float) -> str | None:
        tau, why = efforts_in_order(names, efforts, self._index)
        self.has_effort = tau is not None
        if tau is None:
            self._missing_since = now if self._missing_since is None else self._missing_since
        else:
            self._missing_since = None
        estimate = self.estimator.update(stamp, angles, tau)
        self._note_load(estimate, now)
        if why:
            estimate = ContactEstimate(estimate.stamp, estimate.states, estimate.normal_forces,
                                       estimate.forces, why)
        self.last = estimate
        if estimate.states == self._published_states and (
                now - self._published_at < PUBLISH_PERIOD):
            return None
        self._published_states, self._published_at = estimate.states, now
        reason = estimate.reason or ("" if self._ground_load() else NO_GROUND_LOAD)
        return json.dumps({"stamp": estimate.stamp, **self._report(), "reason": reason})

    def take(self, estimate: ContactEstimate, now: float) -> None:
        """Use ``estimate``, made elsewhere (a replay, a test), as the last one at steady time
        ``now`` [s]: the ground load follows it as it follows `update`'s."""
        with self._lock:
            self.last = estimate
            self._note_load(estimate, now)

    def _note_load(self, estimate: ContactEstimate, now: float) -> None:
        """The ground-load rule: ``estimate`` at steady time ``now`` [s] carries the robot's
        weight when its normal forces add up to more than `GROUND_LOAD`."""
        self._now = now
        if float(np.nansum(estimate.normal_forces)) > GROUND_LOAD:
            self._loaded_at = now

    def report(self) -> dict[str, Any]:
        """``effort`` and ``feet`` (contact, normal force [N] or None) of the last estimate."""
        with self._lock:
            return self._report()

    def _report(self) -> dict[str, Any]:
        feet: dict[str, dict[str, Any]] = {}
        for i, leg in enumerate(self.robot.legs):
            if self.last is None:
                feet[leg] = {"contact": FootContact.UNKNOWN.value, "force": None}
                continue
            force = float(self.last.normal_forces[i])
            feet[leg] = {"contact": self.last.states[i].value,
                         "force": round(force, 3) if math.isfinite(force) else None}
        return {"effort": self.has_effort, "ground_load": self._ground_load(), "feet": feet}

    @property
    def ground_load(self) -> bool:
        """True when the efforts carried the robot's weight within `GROUND_LOAD_WINDOW`."""
        with self._lock:
            return self._ground_load()

    def _ground_load(self) -> bool:
        return self._now - self._loaded_at <= GROUND_LOAD_WINDOW

    def diagnostic(self, now: float) -> tuple[bool, str]:
        """(warn, message) of the ``foot contacts`` status at steady time ``now`` [s]."""
        with self._lock:
            return self._diagnostic(now)

    def _diagnostic(self, now: float) -> tuple[bool, str]:
        if self.last is None:
            return False, "no joint_states yet"
        if self._missing_since is not None and now - self._missing_since >= MISSING_WARN_AFTER:
            return True, f"{self.last.reason}: foot contacts unknown"
        return False, "foot contacts estimated from joint efforts"
