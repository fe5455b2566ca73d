"""The planner's states (the closed set its status JSON reports)."""

from __future__ import annotations

from enum import Enum


class PlannerState(str, Enum):
    """State of `PlannerCore`; the value is the string of ``status()["state"]``.

    Transitions::

        IDLE --stand--> MOVING --> STANDING --walk / cmd_vel--> WALKING --stop--> STOPPING
            --> STANDING
        STANDING --pose--> MOVING --> STANDING (posed; stand: back to neutral)
        IDLE / STANDING --sit--> MOVING --> SITTING --stand--> MOVING --> STANDING
        any --estop--> ESTOP (latched) --reset--> IDLE (publish nothing until a new stand)
        WALKING / STOPPING --a slot that cannot even stop--> HOLDING (holds the pose; stand
            or sit)

    ``MOVING`` is the joint-space move of ``stand`` / ``sit`` or the body move of ``pose``.
    """

    IDLE = "IDLE"
    MOVING = "MOVING"
    STANDING = "STANDING"
    WALKING = "WALKING"
    STOPPING = "STOPPING"
    SITTING = "SITTING"
    HOLDING = "HOLDING"
    ESTOP = "ESTOP"

    def __str__(self) -> str:
        """The bare value, as in the status JSON and in messages."""
        return str.__str__(self)

    def __format__(self, spec: str) -> str:
        return str.__format__(str.__str__(self), spec)


IDLE = PlannerState.IDLE
MOVING = PlannerState.MOVING
STANDING = PlannerState.STANDING
WALKING = PlannerState.WALKING
STOPPING = PlannerState.STOPPING
SITTING = PlannerState.SITTING
HOLDING = PlannerState.HOLDING
ESTOP = PlannerState.ESTOP
#: States in which the tick holds a fixed pose.
HOLDING_STATES = frozenset((STANDING, SITTING, HOLDING))
#: States in which a walk is in progress.
WALK_STATES = frozenset((WALKING, STOPPING))
