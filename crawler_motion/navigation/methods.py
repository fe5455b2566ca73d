"""The navigator's methods: the interface every method implements and the registry (pure)."""

from __future__ import annotations

from typing import Protocol

from crawler_motion.navigation.apf_navigator import ApfNavigator
from crawler_motion.navigation.heading import Rule
from crawler_motion.navigation.navigator import (
    Method,
    NavigatorSettings,
    NavState,
    Output,
    TerrainView,
    VirtualBodyNavigator,
)


class Navigator(Protocol):
    """What the ``navigator`` node and the closed loop use of a method."""

    settings: NavigatorSettings
    state: NavState
    reason: str
    rule: Rule | None

    def set_goal(self, x: float, y: float, now: float) -> None:
        """A new goal (odom frame [m]); `CommandError` for a non-finite one."""

    def cancel(self, reason: str = "cancelled") -> bool:
        """Drop the goal; True when a walk must be stopped."""

    def status(self) -> dict:
        """The ``navigation_status`` fields."""

    def step(self, pose: tuple[float, float, float], radius: float, view: TerrainView,
             now: float) -> Output:
        """One cycle: the twist to send (None: nothing) from pose, virtual radius and map."""


#: The navigator class of each method; the node's ``method`` choices are its keys.
METHODS: dict[Method, type[Navigator]] = {Method.VIRTUAL_BODY: VirtualBodyNavigator,
                                          Method.APF: ApfNavigator}


def make_navigator(method: Method, settings: NavigatorSettings) -> Navigator:
    """A navigator of ``method`` with ``settings``."""
    return METHODS[method](settings)
