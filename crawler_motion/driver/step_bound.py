"""The driver's step bound: no joint command may step further than the joints can move."""

from __future__ import annotations

import numpy as np


class StepBound:
    """The last target sent and the rule bounding the next one.

    A command at steady time ``now`` [s] may differ from the last target sent (after an
    ``enable``: from the measured pose, as the manager holds there) by at most
    ``speed × elapsed + margin`` per joint [rad]; ``elapsed`` is the time since the last sent
    target, at least ``min_elapsed`` [s] (one target period) and at most ``max_elapsed`` [s]
    (the command watchdog: a longer gap trips it anyway).
    """

    def __init__(self, min_elapsed: float) -> None:
        self.min_elapsed = float(min_elapsed)
        self._last: np.ndarray | None = None
        self._last_time = 0.0

    def forget(self) -> None:
        """The next command is bounded from the measured pose (enable, reset, e-stop)."""
        self._last = None

    def check(self, q: np.ndarray, measured: np.ndarray, now: float, speed: float,
              margin: float, max_elapsed: float) -> str:
        """Why ``q`` [rad] steps too far ("" if it does not); see the class docstring."""
        if self._last is None:
            if not np.all(np.isfinite(measured)):
                return "no measured pose yet to bound the first command after enable"
            reference, elapsed, source = measured, self.min_elapsed, "the measured pose"
        else:
            elapsed = min(max(now - self._last_time, self.min_elapsed), max_elapsed)
            reference, source = self._last, "the last sent target"
        allowed = speed * elapsed + margin
        step = np.abs(np.asarray(q, dtype=float) - reference)
        worst = int(np.argmax(step))
        if step[worst] <= allowed:
            return ""
        return (f"step of {step[worst]:.3f} rad on joint {worst} from {source} exceeds "
                f"{allowed:.3f} rad ({speed:g} rad/s x {elapsed:.3f} s + {margin:g} rad)")

    def sent(self, q: np.ndarray, now: float) -> None:
        """``q`` [rad] was accepted and sent at ``now`` [s]."""
        self._last = np.array(q, dtype=float)
        self._last_time = float(now)
