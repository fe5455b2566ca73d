"""Walk requests: a ``walk`` command or a ``cmd_vel`` twist turned into a walk or a change."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

from crawler_motion.errors import CommandError
from crawler_motion.model.config import Config
from crawler_motion.motion.gait import WalkParams
from crawler_motion.planner.commands import (
    STAND_FIRST,
    TWIST_IGNORED,
    Command,
    finite_float,
    is_zero_twist,
    parse_gait_command,
    twist_to_params,
)
from crawler_motion.planner.context import PlannerContext
from crawler_motion.planner.next_slot import Slowed, first_slower
from crawler_motion.planner.state import ESTOP, HOLDING, MOVING, STANDING, STOPPING, WALKING
from crawler_motion.planner.upfront import UpfrontCheck
from crawler_motion.planner.walk import WalkController


class WalkRequests:
    """Accepts or refuses walk commands and twists against the state, then starts the walk on
    ``walk`` or queues new parameters for its next slot boundary."""

    def __init__(self, cfg: Config, ctx: PlannerContext, walk: WalkController) -> None:
        self.cfg = cfg
        self.ctx = ctx
        self.walk_ctl = walk
        self.upfront = UpfrontCheck(cfg)

    def to_check(self, text: str | None, twist: tuple[float, float, float] | None,
                 standing_base: WalkParams) -> tuple[WalkParams, int] | None:
        """The walk (parameters, steps) the gait command ``text``, else the ``twist``, would
        check up front (`walk_to_check`, `twist_to_check`); None for anything else."""
        if text is not None:
            try:
                return self.walk_to_check(parse_gait_command(text, self.cfg), standing_base)
            except CommandError:
                return None
        return None if twist is None else self.twist_to_check(*twist, standing_base)

    def upfront_job(self, text: str | None, twist: tuple[float, float, float] | None,
                    standing_base: WalkParams) -> Callable[[], object] | None:
        """`PlannerCore.upfront_job`: the check of `to_check`'s walk as a job (for a twist,
        with the shares it may start slowed at, `slowed_start`)."""
        walk = self.to_check(text, twist, standing_base)
        if walk is None:
            return None
        if text is None:
            return partial(self._prepare, *walk, slowed=True)
        return partial(self._prepare, *walk)

    def _prepare(self, params: WalkParams, steps: int, slowed: bool = False) -> None:
        """The up-front job: check the walk (for a twist, at the share it may start slowed
        at) and, from standing, plan its first slot (`UpfrontCheck.prepare`)."""
        if slowed:
            params = self.slowed_start(params)[0]
        if self.upfront(params, steps) is None and self.ctx.state == STANDING:
            self.upfront.prepare(params)

    def walk_to_check(self, cmd: Command, standing_base: WalkParams
                      ) -> tuple[WalkParams, int] | None:
        """The walk (parameters, steps) that `walk` would check up front for ``cmd``, found
        without changing anything; None for another command or one refused anyway."""
        ctl = self.walk_ctl
        base = standing_base if self.ctx.state == STANDING else ctl.inputs.newest(ctl.params)
        if cmd.kind != "walk" or base is None:
            return None
        try:
            return cmd.apply(base, self.cfg), cmd.steps or 1
        except CommandError:
            return None

    def twist_to_check(self, vx: float, vy: float, wz: float, standing_base: WalkParams
                       ) -> tuple[WalkParams, int] | None:
        """The walk that `twist` would check up front (a twist that starts a walk from
        standing), found without changing anything; None otherwise."""
        if self.ctx.state != STANDING or is_zero_twist(vx, vy, wz):
            return None
        try:
            return twist_to_params(vx, vy, wz, self.cfg, standing_base), 1
        except CommandError:
            return None

    def _check_upfront(self, params: WalkParams, steps: int, now: float) -> None:
        error = self.upfront(params, steps)
        if error is not None:
            self.ctx.journal.refuse(f"walk refused as a whole: {error}", now)

    def _apply(self, cmd: Command, base: WalkParams, now: float) -> WalkParams:
        try:
            return cmd.apply(base, self.cfg)
        except CommandError as exc:
            self.ctx.journal.refuse(str(exc), now)

    def walk(self, cmd: Command, standing_base: WalkParams, move_target: str, now: float
             ) -> None:
        """A ``walk`` command at ``now`` [s]: from STANDING a walk with ``standing_base``
        overridden; while WALKING new parameters at the next slot boundary."""
        ctx, ctl = self.ctx, self.walk_ctl
        state = ctx.state
        if state not in (STANDING, WALKING):
            hint = {ESTOP: "e-stop latched; send reset, then stand",
                    STOPPING: "stopping; wait for STANDING",
                    MOVING: f"a {move_target} move is in progress; wait for it to end"}
            ctx.journal.refuse(f"walk refused in state {state}: "
                               f"{hint.get(state, 'send stand first')}", now)
        if state == STANDING:
            if ctx.paused:
                ctx.journal.refuse(f"walk refused: {ctx.paused_reason()}", now)
            self._refuse_posed("walk refused", now)
            base = standing_base
        else:
            base = ctl.inputs.newest(ctl.params)
            assert base is not None
        params = self._apply(cmd, base, now)
        if state == WALKING:
            assert ctl.params is not None
            if params.gait != ctl.params.gait:
                ctx.journal.refuse(f"walk refused: the gait can only change while standing "
                                   f"({ctl.params.gait} -> {params.gait}); send stop first",
                                   now)
        self._check_upfront(params, cmd.steps or 1, now)
        if state == STANDING:
            ctl.start(params, cmd.steps, "command", now, self.upfront.take_first(params))
            return
        ctl.inputs.take_command(params, cmd.steps)
        ctl.source = "command"
        ctx.journal.touch(now)
        ctx.journal.event("info", f"walk parameters change at the next slot boundary "
                                  f"({cmd.steps or 'until stopped'} steps)")

    def twist(self, vx: float, vy: float, wz: float, standing_base: WalkParams, now: float,
              resuming: bool = False) -> None:
        """A ``cmd_vel`` twist (m/s, m/s, rad/s) at ``now`` [s]; see `PlannerCore.on_twist`
        (``resuming``: a resume from the measured pose is due or runs)."""
        ctx, ctl = self.ctx, self.walk_ctl
        for name, value in (("linear.x", vx), ("linear.y", vy), ("angular.z", wz)):
            if finite_float(value) is None:
                ctx.journal.refuse(f"cmd_vel {name} must be a finite number, got "
                                   f"{value!r:.40}", now)
        zero = is_zero_twist(vx, vy, wz)
        if ctx.state == WALKING and ctl.source == "cmd_vel":
            if zero:
                ctl.last_twist = now
                ctl.request_stop(now, "zero cmd_vel: stopping into standing")
                return
            base = ctl.inputs.newest(ctl.params)
            assert base is not None
            params = self._from_twist(vx, vy, wz, base, now)
            ctl.last_twist = now
            ctl.take_twist(params, now)
            return
        if zero:
            return
        if ctx.state != STANDING:
            hint = ("send stop first" if ctx.state == WALKING
                    else "wait for STANDING" if ctx.state in (STOPPING, MOVING)
                    else "wait for the resume from the measured pose"
                    if resuming and ctx.state == HOLDING
                    else STAND_FIRST)
            ctx.journal.refuse(f"{TWIST_IGNORED} in state {ctx.state}: {hint}", now)
        if ctx.paused:
            ctx.journal.refuse(ctx.paused_reason(), now)
        self._refuse_posed(TWIST_IGNORED, now)
        asked = self._from_twist(vx, vy, wz, standing_base, now)
        params, slowed = self.slowed_start(asked)
        self._check_upfront(params, 1, now)
        ctl.start(params, None, "cmd_vel", now, self.upfront.take_first(params))
        ctl.inputs.asked = asked  # the next slots ask for the twist's own stride
        ctl.last_twist = now
        ctx.journal.slowed(slowed, now)

    def slowed_start(self, params: WalkParams) -> tuple[WalkParams, Slowed | None]:
        """A twist's walk from standing, or at the first of `next_slot.SLOWED_SHARES` of its
        stride and turn that the up-front check passes (the check refuses it if none does).
        Tens of ms per check: the node runs it once without its lock first (the verdicts are
        cached)."""
        error = self.upfront(params, 1)
        if error is None:
            return params, None
        found = first_slower(params, lambda slower: slower if self.upfront(slower, 1) is None
                             else None)
        return (params, None) if found is None else (found[1], Slowed(found[0], error))

    def _refuse_posed(self, what: str, now: float) -> None:
        """Refuse a walk from a posed body: walks start from the neutral standing pose."""
        pose = self.ctx.body_pose
        if not pose.is_neutral:
            self.ctx.journal.refuse(f"{what}: the body is posed ({pose.described()}); walks "
                                    f"start from the neutral pose: {STAND_FIRST}", now)

    def _from_twist(self, vx: float, vy: float, wz: float, base: WalkParams, now: float
                    ) -> WalkParams:
        try:
            return twist_to_params(vx, vy, wz, self.cfg, base)
        except CommandError as exc:
            journal = self.ctx.journal
            journal.record_refusal(str(exc), now)
            journal.refused_twist = [float(vx), float(vy), float(wz)]
            raise
