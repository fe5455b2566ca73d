"""The planner's ``planner_status`` object (the JSON the node publishes), built from the core."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from crawler_motion.planner.state import MOVING

if TYPE_CHECKING:
    from crawler_motion.planner.core import PlannerCore


def planner_status(core: PlannerCore, late_ticks: int, stand_height: float) -> dict[str, Any]:
    """State, gait, profile, step k of N (k full gait cycles done), pause, resume in progress,
    the driver's last reported state, last refusal, ``late_ticks``, the ``stand_height`` [m]
    and the body pose (x, y, z [m], roll, pitch, yaw [rad]) of the core, and the foot
    ``contacts`` (`contacts.ContactMonitor.report`)."""
    ctx, walk, journal = core.ctx, core.walk, core.ctx.journal
    params = walk.params if walk.params is not None else core.defaults
    return {
        "state": ctx.state,
        "target": core.moves.target if ctx.state == MOVING else None,
        "gait": params.gait,
        "profile": params.profile,
        "step": walk.steady_done // walk.groups,
        "steps": walk.steps_total,
        "source": walk.source,
        "phase": walk.seq.phase if walk.seq is not None else None,
        "paused": ctx.paused,
        "pause_reason": ctx.pause_reason or None,
        "body_height": stand_height,
        "body_pose": ctx.body_pose.as_dict(),
        "last_refusal": journal.last_refusal,
        "refusals": journal.refusals,
        "twist_refusals": journal.twist_refusals,
        "refused_twist": journal.refused_twist,
        "last_event": journal.last_event,
        "slowed_slots": journal.slowed_slots,
        "slowed_share": journal.slowed_share,
        "late_ticks": late_ticks,
        "resuming": core.resumer.active,
        "interruptions": core.resumer.interruptions,
        "driver": core.driver.report.state if core.driver.report else None,
        "contacts": core.contacts.report(),
        "revision": journal.revision,
        "stamp": journal.stamp,
    }
