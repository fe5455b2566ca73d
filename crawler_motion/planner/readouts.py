"""What a planner core shows without changing it: state, pause, revision, walk parameters and
events (a mixin of `core.PlannerCore`; its ``ctx`` and ``walk`` are read)."""

from __future__ import annotations

from crawler_motion.motion.gait import WalkParams
from crawler_motion.planner.context import PlannerContext
from crawler_motion.planner.state import PlannerState
from crawler_motion.planner.walk import WalkController


class CoreReadouts:
    """Read-only views of the planner's context and walk."""

    ctx: PlannerContext
    walk: WalkController

    @property
    def state(self) -> PlannerState:
        """The current state."""
        return self.ctx.state

    @property
    def paused(self) -> bool:
        """True while a motor-manager fault pauses the gait."""
        return self.ctx.paused

    @property
    def pause_reason(self) -> str:
        """Why the gait is paused ("" when not paused)."""
        return self.ctx.pause_reason

    @property
    def revision(self) -> int:
        """Incremented on every change of `status` (except ``late_ticks``)."""
        return self.ctx.journal.revision

    @property
    def walk_params(self) -> WalkParams | None:
        """Parameters of the slot being walked (None when not walking)."""
        return self.walk.params

    def pop_events(self) -> list[tuple[str, str]]:
        """Events since the last call, as ``(level, message)``; level info, warn or error."""
        return self.ctx.journal.pop_events()
