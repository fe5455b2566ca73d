"""What holds the navigator's walk (pure): a map stale in content, another ``cmd_vel``
publisher, a planner refusal of a twist the navigator did not send.

**Map freshness.** The mapper publishes ``terrain_map`` at its own rate whether or not it
fuses scans, so a fresh header stamp says nothing of the content. ``terrain_mapper`` puts the
stamp of the last scan it fused in ``OccupancyGrid.info.map_load_time`` (zero: none fused
since it started or since its odometry restarted). `MapFreshness` turns that into the content
age on the navigator's steady clock: the age when a new content stamp arrives (navigator
clock minus the stamp, at least 0), growing from then on until the next new stamp. A mapper
killed, stopped or skipping every scan therefore ages its map, even though the navigator may
still receive grids (or none at all).

**Foreign publishers.** The navigator is meant to be the only node steering ``cmd_vel``: a
twist on the topic that is none of its own (`SentTwists`) is another node's; the node names
the topic's other publishers from the ROS graph (`foreign_publishers`).

**Refusal attribution.** `SentTwists` remembers the navigator's recent twists, so a refusal
of a twist it never sent (another node's) is not blamed on it.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence

#: The navigator's own twists remembered for attributing refusals.
SENT_MEMORY = 64


class MapFreshness:
    """Content age of the map from its ``map_load_time`` stamps (see the module docstring)."""

    def __init__(self) -> None:
        self._load: float | None = None
        self._fused_at = -math.inf  # steady time of the content [s]

    def note(self, load_time: float, clock_now: float, steady_now: float) -> None:
        """A map whose last fused scan is stamped ``load_time`` [s] (0: none), received at
        navigator clock ``clock_now`` [s] (same time base as the stamp) and steady time
        ``steady_now`` [s]."""
        if not (math.isfinite(load_time) and load_time > 0.0):
            self._load, self._fused_at = None, -math.inf
            return
        if load_time != self._load:
            self._load = load_time
            self._fused_at = steady_now - max(0.0, clock_now - load_time)

    def age(self, steady_now: float) -> float:
        """Age of the map's content [s] at steady time ``steady_now`` (inf: no content)."""
        return steady_now - self._fused_at

    def stale_reason(self, steady_now: float, max_age: float) -> str | None:
        """Why the map may not be steered by (content older than ``max_age`` [s]); None when
        it is fresh."""
        age = self.age(steady_now)
        if age <= max_age:
            return None
        if not math.isfinite(age):
            return ("waiting for a fresh map: terrain_map holds no fused scan (mapper not "
                    "running, restarted or skipping every scan); the robot stands")
        return (f"waiting for a fresh map: its last fused scan is {age:.2f} s old "
                f"(map_max_age {max_age:g} s; mapper stopped or skipping scans); the robot "
                "stands")


def foreign_publishers(publishers: Iterable[tuple[str, str]], own: tuple[str, str]
                       ) -> list[str]:
    """Full names (``/ns/node``) of the publishers ``(node name, namespace)`` other than
    ``own``, sorted, once each."""
    names = {_full_name(name, ns) for name, ns in publishers if (name, ns) != own}
    return sorted(names)


def foreign_reason(names: Sequence[str], hold: float) -> str:
    """The hold reason while another node's twists arrive on ``cmd_vel`` (``names``: the
    topic's other publishers; ``hold`` [s]: how long after the last such twist)."""
    who = ", ".join(names) if names else "a node gone already"
    return (f"held: another node steers cmd_vel (its publishers besides the navigator: {who});"
            f" the navigator does not steer while it does (it resumes {hold:g} s after that "
            "node's last twist)")


def _full_name(name: str, namespace: str) -> str:
    ns = namespace.rstrip("/")
    return f"{ns}/{name}" if ns else f"/{name}"


class SentTwists:
    """The navigator's last `SENT_MEMORY` twists ``(vx, vy, wz)``, and those of them not yet
    heard back on ``cmd_vel`` (`echo`): a twist heard that it did not send, or more often than
    it sent it (another node's zero twists, say), is another node's."""

    def __init__(self) -> None:
        self._sent: deque[tuple[float, float, float]] = deque(maxlen=SENT_MEMORY)
        self._unheard: deque[tuple[float, float, float]] = deque(maxlen=SENT_MEMORY)

    def add(self, twist: Sequence[float]) -> None:
        """Remember one twist sent (m/s, m/s, rad/s)."""
        key = (float(twist[0]), float(twist[1]), float(twist[2]))
        self._sent.append(key)
        self._unheard.append(key)

    def echo(self, twist: Sequence[float]) -> bool:
        """A twist heard on ``cmd_vel``: True if it is one the navigator sent and had not
        heard yet (its own), False if another node's."""
        key = (float(twist[0]), float(twist[1]), float(twist[2]))
        try:
            self._unheard.remove(key)
        except ValueError:
            return False
        return True

    def __contains__(self, twist: object) -> bool:
        try:
            key = tuple(float(v) for v in twist)  # type: ignore[attr-defined]
        except (TypeError, ValueError):
            return False
        return key in self._sent
