"""The up-front check of a new walk: `plan_walk` over a few steps, cached."""

from __future__ import annotations

from crawler_motion.errors import GaitError, KinematicsError, TrajectoryError
from crawler_motion.model.config import Config
from crawler_motion.motion.gait import WalkParams, plan_walk

#: A finite walk is checked up front with `plan_walk` for at most this many steps: the steady
#: state of a walk with fixed parameters is periodic with one step, so a longer walk consists
#: of the same slots (checked again, one by one, before each starts).
UPFRONT_CHECK_STEPS = 3
#: Up-front check results remembered (by walk parameters and steps).
UPFRONT_CACHE_SIZE = 64


class UpfrontCheck:
    """Checks whole walks with `plan_walk` (tens of ms) and remembers the verdicts: a joystick
    held still repeats its twist."""

    def __init__(self, cfg: Config) -> None:
        self.cfg = cfg
        self._verdicts: dict[tuple[WalkParams, int], str | None] = {}

    def __call__(self, params: WalkParams, steps: int) -> str | None:
        """None if a walk of ``steps`` steps with ``params`` can be executed, else why not."""
        key = (params, min(steps, UPFRONT_CHECK_STEPS))
        if key not in self._verdicts:
            try:
                plan_walk(self.cfg, params, key[1])
                self._verdicts[key] = None
            except (GaitError, KinematicsError, TrajectoryError) as exc:
                self._verdicts[key] = str(exc)
            if len(self._verdicts) > UPFRONT_CACHE_SIZE:
                del self._verdicts[next(iter(self._verdicts))]
        return self._verdicts[key]
