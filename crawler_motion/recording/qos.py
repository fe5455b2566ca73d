"""QoS of the recorded topics: what the stack's publishers offer, what the recorder requests, and
the ``offered_qos_profiles`` channel metadata ``ros2 bag`` writes.

The stack's own publishers (read from the nodes) are all reliable; ``planner_status``,
``driver_status`` and ``navigation_status`` are also transient local (latched). The recorder
subscribes to those topics at start with that QoS, so nothing is lost while the graph is polled.
Other topics, and known topics whose publishers offer less (a best-effort ``cmd_vel`` from a
joystick driver), get the QoS every publisher on the graph offers (`adapted_qos`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import yaml

#: Subscription queue depth: deep, so a busy recorder does not drop messages.
DEPTH = 100
#: Topics the stack publishes transient local (latched); the others are reliable and volatile.
LATCHED = frozenset({"planner_status", "driver_status", "navigation_status"})
#: Keep-last depth of the stack's publishers: 1 for the latched status topics, else 10.
LATCHED_DEPTH = 1
PUBLISHER_DEPTH = 10
RELIABLE, BEST_EFFORT = "reliable", "best_effort"
TRANSIENT_LOCAL, VOLATILE = "transient_local", "volatile"


@dataclass(frozen=True)
class Qos:
    """A QoS by policy names (as rclpy's enums name them, lower case); durations unset."""

    reliability: str
    durability: str
    depth: int
    history: str = "keep_last"
    liveliness: str = "system_default"
    avoid_ros_namespace_conventions: bool = False


def _name(value: Any) -> str:
    """A policy's lower-case name: of an rclpy enum, or a name already."""
    return str(getattr(value, "name", value)).lower()


def declared_qos(topic: str) -> Qos:
    """The QoS the stack's publisher of ``topic`` declares (``topic`` as in `STACK_TOPICS`)."""
    latched = topic.lstrip("/") in LATCHED
    return Qos(RELIABLE, TRANSIENT_LOCAL if latched else VOLATILE,
               LATCHED_DEPTH if latched else PUBLISHER_DEPTH)


def requested_qos(offered: Sequence[Any]) -> Qos:
    """The subscription QoS matching every profile in ``offered`` (`Qos` or rclpy profiles):
    reliable and transient local only when all of them offer it (as ``ros2 bag`` does), depth
    `DEPTH`."""
    reliable = all(_name(p.reliability) == RELIABLE for p in offered)
    latched = all(_name(p.durability) == TRANSIENT_LOCAL for p in offered)
    return Qos(RELIABLE if reliable else BEST_EFFORT, TRANSIENT_LOCAL if latched else VOLATILE,
               DEPTH)


def adapted_qos(publishers: Sequence[Any]) -> Qos:
    """`requested_qos` of the publishers found on the graph (``TopicEndpointInfo``)."""
    return requested_qos([p.qos_profile for p in publishers])


def compatible(requested: Any, offered: Any) -> bool:
    """Whether a subscription with ``requested`` receives from a publisher ``offered`` (the
    two policies that decide it: reliability and durability)."""
    if _name(requested.reliability) == RELIABLE and _name(offered.reliability) != RELIABLE:
        return False
    return not (_name(requested.durability) == TRANSIENT_LOCAL
                and _name(offered.durability) != TRANSIENT_LOCAL)


def _duration(value: Any) -> dict[str, int]:
    sec, nsec = divmod(int(getattr(value, "nanoseconds", 0)), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def profile_dict(profile: Any) -> dict[str, Any]:
    """One profile (`Qos` or an rclpy profile) as ``ros2 bag`` (Jazzy, metadata version 9)
    serialises it: policy names in lower case, durations as ``sec`` / ``nsec``."""
    return {
        "history": _name(profile.history),
        "depth": int(profile.depth),
        "reliability": _name(profile.reliability),
        "durability": _name(profile.durability),
        "deadline": _duration(getattr(profile, "deadline", None)),
        "lifespan": _duration(getattr(profile, "lifespan", None)),
        "liveliness": _name(profile.liveliness),
        "liveliness_lease_duration": _duration(getattr(profile, "liveliness_lease_duration",
                                                       None)),
        "avoid_ros_namespace_conventions": bool(profile.avoid_ros_namespace_conventions),
    }


def offered_qos_profiles(profiles: Sequence[Any]) -> str:
    """The ``offered_qos_profiles`` channel metadata: a YAML list, one entry per publisher."""
    return yaml.safe_dump([profile_dict(p) for p in profiles], sort_keys=False,
                          default_flow_style=False)
