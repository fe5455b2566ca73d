"""The faults of a mission soak: their kinds, what each must do to the robot, a seeded plan.

A fault is one of `FaultKind` on a target process (kills and stops) or on the robot's inputs
(CAN garbage, an e-stop, a future-stamped odometry message, a flood of refused goals). Each
kind has an `Expectation`: whether the robot must come to a hold and within how long of the
fault's start, and the documented way back (`Recovery`, docs/safety.md "After a fault"). The
plan is drawn from a seed: every kind in turn (shuffled per round), each after a quiet walk of
a drawn length, so a run of a given seed and length injects the same faults in the same order.
No ROS here.
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from enum import Enum

#: The processes a kill or a stop hits (``crawler-motion sim --split``'s names).
TARGETS = ("terrain_mapper", "navigator", "planner_node", "driver_node")
#: Length of a SIGSTOP [s] (drawn in this range).
STOP_RANGE = (1.0, 3.0)
#: Quiet walking between the recovery of one fault and the next fault [s] (drawn).
QUIET_RANGE = (15.0, 45.0)


class FaultKind(Enum):
    """What is done."""

    KILL = "kill"  # SIGKILL, then the process is started again
    STOP = "stop"  # SIGSTOP for `Fault.length` seconds, then SIGCONT
    CAN_GARBAGE = "can_garbage"  # random frames on the motors' bus for `Fault.length` s
    ESTOP = "estop"  # crawler-motion console estop
    FUTURE_ODOM = "future_odom"  # one odom message stamped an hour ahead
    GOAL_FLOOD = "goal_flood"  # goals out of range at 1 kHz for `Fault.length` s


class Recovery(Enum):
    """The documented way back to walking the mission."""

    NONE = "none"  # the robot never stopped: the mission goes on
    AUTOMATIC = "automatic"  # it holds while the fault lasts and goes on by itself
    RESEND = "resend mission"  # the mission is sent again (the navigator lost it)
    RECOVER = "console recover, stand, resend mission"  # the motion chain ended the walk


@dataclass(frozen=True)
class Fault:
    """One fault: ``kind`` on ``target`` (a process of `TARGETS`, or None), lasting
    ``length`` [s] (stops, bursts, floods), injected after ``quiet`` [s] of walking."""

    kind: FaultKind
    target: str | None
    length: float
    quiet: float

    @property
    def name(self) -> str:
        """``kind`` or ``kind target``."""
        return self.kind.value if self.target is None else f"{self.kind.value} {self.target}"


@dataclass(frozen=True)
class Expectation:
    """What a fault must do: come to a hold (body still) within ``hold_within`` [s] of its
    start when ``hold`` (for a stop: only when it lasts that long; ``detect`` [s] is the time
    the chain takes to notice it), and come back by ``recovery``."""

    hold: bool
    hold_within: float
    detect: float
    recovery: Recovery


#: Time a walk takes to stop into standing once told to [s] (half a step at most; measured
#: on the real-time stack: see docs/running.md "Mission soak").
STOP_TIME = 2.0


def expectation(fault: Fault) -> Expectation:
    """The `Expectation` of ``fault`` (the chain's parameters of the simulated bring-up:
    navigator ``map_max_age`` 1 s, planner ``cmd_vel_timeout`` 0.5 s, driver
    ``command_timeout`` 1 s, the manager's command watchdog)."""
    kind, target = fault.kind, fault.target
    if kind in (FaultKind.FUTURE_ODOM, FaultKind.GOAL_FLOOD, FaultKind.CAN_GARBAGE):
        return Expectation(False, 0.0, 0.0, Recovery.NONE)
    if kind is FaultKind.ESTOP:
        return Expectation(True, 1.0, 0.0, Recovery.RECOVER)
    detect = {"terrain_mapper": 1.0, "navigator": 0.5, "planner_node": 1.0,
              "driver_node": 0.5}[str(target)]
    if kind is FaultKind.KILL:
        recovery = {"terrain_mapper": Recovery.AUTOMATIC, "navigator": Recovery.RESEND,
                    "planner_node": Recovery.RECOVER, "driver_node": Recovery.RECOVER}
        return Expectation(True, detect + STOP_TIME, detect, recovery[str(target)])
    recovery = {"terrain_mapper": Recovery.AUTOMATIC, "navigator": Recovery.AUTOMATIC,
                "planner_node": Recovery.RECOVER, "driver_node": Recovery.RECOVER}
    # a stop shorter than the time to notice it and stop the walk cannot leave the body still
    return Expectation(fault.length >= detect + STOP_TIME, detect + STOP_TIME, detect,
                       recovery[str(target)])


def kinds_and_targets() -> list[tuple[FaultKind, str | None]]:
    """Every (kind, target) a plan draws from: kill and stop of each of `TARGETS`, and the
    input faults."""
    out: list[tuple[FaultKind, str | None]] = []
    for kind in (FaultKind.KILL, FaultKind.STOP):
        out += [(kind, t) for t in TARGETS]
    out += [(k, None) for k in (FaultKind.CAN_GARBAGE, FaultKind.ESTOP, FaultKind.FUTURE_ODOM,
                                FaultKind.GOAL_FLOOD)]
    return out


def fault_plan(seed: int, count: int, quiet: tuple[float, float] = QUIET_RANGE) -> list[Fault]:
    """``count`` faults drawn from ``seed``: rounds of every kind of `kinds_and_targets` in a
    shuffled order, each after a quiet walk drawn in ``quiet`` [s]."""
    if count < 0:
        raise ValueError(f"fault count {count} is negative: give 0 or more")
    if not 0.0 <= quiet[0] <= quiet[1]:
        raise ValueError(f"quiet range {quiet} is not 0 <= low <= high [s]")
    rng = random.Random(seed)
    out: list[Fault] = []
    while len(out) < count:
        round_ = kinds_and_targets()
        rng.shuffle(round_)
        for kind, target in round_[:count - len(out)]:
            length = {FaultKind.STOP: rng.uniform(*STOP_RANGE), FaultKind.CAN_GARBAGE: 1.0,
                      FaultKind.GOAL_FLOOD: 2.0}.get(kind, 0.0)
            out.append(Fault(kind, target, round(length, 2), round(rng.uniform(*quiet), 1)))
    return out
