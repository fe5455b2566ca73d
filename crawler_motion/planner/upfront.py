"""The up-front check of a new walk (`plan_walk` over a few steps, cached) and its first slot,
planned before the walk starts."""

from __future__ import annotations

from dataclasses import dataclass

from crawler_motion.errors import GaitError, KinematicsError, TrajectoryError
from crawler_motion.model.config import Config
from crawler_motion.motion.fastpath import Track
from crawler_motion.motion.gait import (
    GaitSequencer,
    Slot,
    WalkParams,
    check_trajectories,
    plan_walk,
)
from crawler_motion.planner.footholds import SlotFacts, slot_facts

#: A finite walk is checked up front with `plan_walk` for at most this many steps: the steady
#: state of a walk with fixed parameters is periodic with one step, so a longer walk consists
#: of the same slots (checked again, one by one, before each starts).
UPFRONT_CHECK_STEPS = 3
#: Up-front check results remembered (by walk parameters and steps).
UPFRONT_CACHE_SIZE = 64


@dataclass(frozen=True)
class FirstSlot:
    """A new walk's first slot, planned and checked: the sequencer after it, and (when made
    ahead of the start) its evaluator and the footholds' facts (`slot_facts`)."""

    params: WalkParams
    seq: GaitSequencer
    slot: Slot
    track: Track | None = None
    facts: SlotFacts | None = None


def first_slot(cfg: Config, params: WalkParams, ahead: bool = False) -> FirstSlot:
    """Plan and check the first slot of a walk with ``params`` (tens of ms); ``ahead``: with
    its evaluator and facts too (a few ms more). Raises `GaitError`, `KinematicsError` or
    `TrajectoryError`."""
    seq = GaitSequencer(cfg, params)
    slot = seq.next_slot(stopping=False)
    assert slot is not None
    check_trajectories(cfg.robot, slot.legs, "the first slot")
    if not ahead:
        return FirstSlot(params, seq, slot)
    return FirstSlot(params, seq, slot, Track(slot.legs), slot_facts(slot, cfg.robot))


class UpfrontCheck:
    """Checks whole walks with `plan_walk` (tens of ms) and remembers the verdicts: a joystick
    held still repeats its twist."""

    def __init__(self, cfg: Config) -> None:
        self.cfg = cfg
        self._verdicts: dict[tuple[WalkParams, int], str | None] = {}
        self._first: FirstSlot | None = None  # the last one prepared and not taken

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

    def prepare(self, params: WalkParams) -> None:
        """Plan the first slot of a walk with ``params`` that passed the check, for
        `take_first` (the node does it without its lock, so that the start under it only
        commits the slot). One is kept; a walk that cannot start is left to the start."""
        if self._first is not None and self._first.params == params:
            return
        try:
            self._first = first_slot(self.cfg, params, ahead=True)
        except (GaitError, KinematicsError, TrajectoryError):
            self._first = None

    def take_first(self, params: WalkParams) -> FirstSlot | None:
        """The first slot `prepare` made for ``params`` (once), else None."""
        first, self._first = self._first, None
        return first if first is not None and first.params == params else None
