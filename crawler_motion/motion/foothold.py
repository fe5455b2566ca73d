"""Terrain-adaptive touch-down: a vertical offset per foot on top of the planned targets
(pure: no rclpy).

Each leg ``i`` carries an offset δ_i(t) [m] along base_link z, 0 on flat ground; its foot
target is the planned one plus ``(0, 0, δ_i)`` and its velocity the planned one plus
``(0, 0, δ_i')``. δ is C² at every event, so the targets stay C²:

- **early contact**: contact "yes" while the leg lowers (the swing's ``lower`` phase) and the
  foot target is still more than ``tolerance`` above the planned ground: the target z, from its
  state (z, ż, z̈) at that instant, follows a quintic to rest at ``z + ż·stop_time/2`` over
  ``stop_time``; δ = that quintic minus the plan from then on (C² because the quintic starts
  with the plan's state), constant once the plan is on the ground: the foot stays where it
  landed, through the stance;
- **search**: a swing that ends with contact "no" lowers further, δ a C² speed-up from rest to
  ``search_speed``, then a C² slow-down to rest at ``-search_depth``, until contact (then the
  same stop, which may land up to ``search_speed·stop_time/2`` deeper); the search's end
  without contact is a failure naming the leg and the depth (the walk ends holding the pose:
  no foot keeps descending);
- **lift from the foothold**: over the next swing of the leg, from lift-off to the start of
  its lowering, δ blends from the held value back to 0 with the rest profile, so each swing
  lowers to the planned ground again and adapts again;
- contacts "unknown" (no efforts): no event, δ stays as it is (0 on a blind walk).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from crawler_motion.errors import ConfigError
from crawler_motion.model.yaml_values import number_in
from crawler_motion.motion.contact_estimation import FootContact
from crawler_motion.motion.trajectory import Piecewise

#: Times closer than this count as equal (slot arithmetic rounding) [s].
TIME_EPS = 1e-9
#: Duration of the search's speed-up and slow-down [s]: slow enough that the contact
#: estimate's lag at an on-time touch-down costs a fraction of a millimetre.
SEARCH_RAMP = 0.15
#: Consecutive contact estimates at ``touch_force`` that make an early contact (a swinging
#: leg's accelerations alone reach it for single samples).
EARLY_CONFIRM = 2


@dataclass(frozen=True)
class FootholdSettings:
    """``enabled`` (off by default: on the real-time stack it does not help the default gait,
    docs/seabed.md; when on, the planner walks the blind plan while the efforts carry no
    ground load, `planner.contacts.ContactMonitor.ground_load`); early-contact
    ``tolerance`` above the planned ground [m],
    ``stop_time`` of the smooth stop [s], ``search_depth`` below the planned ground [m], the
    search's peak ``search_speed`` [m/s] and the normal force [N] an early contact needs
    (`EARLY_CONFIRM` estimates in a row; the contact threshold alone is met by a swinging
    leg's dynamics)."""

    enabled: bool = False
    tolerance: float = 0.006
    stop_time: float = 0.04
    search_depth: float = 0.02
    search_speed: float = 0.02
    touch_force: float = 2.0

    def __post_init__(self) -> None:
        for name, lo, hi, unit in (("tolerance", 0.0, 0.05, "m"), ("stop_time", 0.005, 1.0, "s"),
                                   ("touch_force", 0.0, 100.0, "N"),
                                   ("search_depth", 0.0, 0.1, "m"),
                                   ("search_speed", 0.001, 1.0, "m/s")):
            number_in(getattr(self, name), f"foothold {name}", lo, hi, unit)
        if not isinstance(self.enabled, bool):
            raise ConfigError(f"foothold enabled must be true or false, got {self.enabled!r}")

    @property
    def search_ramp(self) -> float:
        """Duration [s] of the search's speed-up (and slow-down): `SEARCH_RAMP`, shorter when
        the depth is too small to reach full speed."""
        return min(SEARCH_RAMP, self.search_depth / self.search_speed)

    @property
    def search_time(self) -> float:
        """Duration [s] of the search from 0 to ``-search_depth``, at rest at both ends."""
        return self.search_depth / self.search_speed + self.search_ramp

    def search(self, s: float) -> tuple[float, float, float]:
        """Depth below the planned ground [m] (positive down), its rate and acceleration
        ``s`` [s] into the search: a C² speed-up to ``search_speed``, constant speed, a C²
        slow-down to rest at ``search_depth`` (the speed-up's rate is ``3u² - 2u³``)."""
        v, ramp, total = self.search_speed, self.search_ramp, self.search_time
        if s <= 0.0 or ramp <= 0.0:
            return 0.0, 0.0, 0.0
        if s >= total:
            return self.search_depth, 0.0, 0.0
        mirror = s > total - ramp
        u = min((total - s if mirror else s) / ramp, 1.0)
        pos = v * ramp * u**3 * (1.0 - u / 2.0)
        if u >= 1.0:  # cruising
            return v * ramp / 2.0 + v * (s - ramp), v, 0.0
        rate, acc = v * u * u * (3.0 - 2.0 * u), 6.0 * v * u * (1.0 - u) / ramp
        return (self.search_depth - pos, rate, -acc) if mirror else (pos, rate, acc)


class Mode(str, Enum):
    """What a leg's offset does now."""

    HELD = "held"  # constant
    BLEND = "blend"  # rest profile from the held value to 0
    STOP = "stop"  # quintic stop minus the plan
    SEARCH = "search"  # speed-up, constant speed, slow-down below the planned ground


def rest(u: float) -> tuple[float, float, float]:
    """The rest profile ``10u³ - 15u⁴ + 6u⁵`` and its first two derivatives in ``u``
    (clamped to [0, 1])."""
    u = 0.0 if u < 0.0 else (1.0 if u > 1.0 else u)
    return (u**3 * (10.0 + u * (-15.0 + 6.0 * u)), 30.0 * u * u * (1.0 - u) ** 2,
            60.0 * u * (1.0 - u) * (1.0 - 2.0 * u))


def stop_quintic(z: float, v: float, a: float, duration: float) -> tuple[float, ...]:
    """Coefficients (in ``s = t - t_c`` [s], ascending) of the quintic from position ``z``
    [m], velocity ``v`` [m/s] and acceleration ``a`` [m/s²] to rest at ``z + v·duration/2``
    after ``duration`` [s]."""
    t = duration
    d = v * t / 2.0  # the travel to the landing point
    h0 = d - v * t - a * t * t / 2.0  # residual position, velocity, acceleration at the end
    h1 = -v - a * t
    h2 = -a
    c3 = (10.0 * h0 - 4.0 * h1 * t + h2 * t * t / 2.0) / t**3
    c4 = (-15.0 * h0 + 7.0 * h1 * t - h2 * t * t) / t**4
    c5 = (6.0 * h0 - 3.0 * h1 * t + h2 * t * t / 2.0) / t**5
    return (z, v, a / 2.0, c3, c4, c5)


def lowering_start(plan: Piecewise, swing_time: float) -> float:
    """Slot time [s] a swing of ``swing_time`` [s] along ``plan`` starts lowering (its first
    ``lower`` segment; half the swing if it has none)."""
    lower = [b for b, phase in zip(plan.breaks[:-1], plan.phases, strict=True)
             if phase == "lower" and b < swing_time]
    return float(lower[0]) if lower else 0.5 * swing_time


def polynomial(c: Sequence[float], s: float) -> tuple[float, float, float]:
    """Value and first two derivatives of the polynomial ``c`` (ascending) at ``s``."""
    p = dp = ddp = 0.0
    for k in range(len(c) - 1, -1, -1):
        ddp = ddp * s + 2.0 * dp
        dp = dp * s + p
        p = p * s + c[k]
    return p, dp, ddp


@dataclass
class _Swing:
    """One planned swing of a leg, times [s] on the adapter's clock; ``plan`` in slot time
    from ``t0``."""

    t0: float
    t_lower: float
    t_end: float
    z_ground: float  # planned foot z at touch-down [m]
    plan: Piecewise


@dataclass
class _Leg:
    mode: Mode = Mode.HELD
    value: float = 0.0  # HELD: δ; BLEND: start value
    t_start: float = 0.0  # BLEND / STOP / SEARCH start [s]
    duration: float = 0.0  # BLEND / STOP / SEARCH duration [s]
    stop: tuple[float, ...] = ()  # STOP: quintic of the target z
    ground: float = 0.0  # STOP / SEARCH: the planned ground z of the last swing [m]
    swing: _Swing | None = None
    pressed: int = 0  # consecutive estimates at the touch force
    last: float = 0.0  # the offset `offsets` gave last [m]


class FootholdAdapter:
    """Per-leg vertical offsets δ of the planned foot targets; see the module docstring.

    Per tick: `begin_swing` for each leg a new slot swings, then `update` (events; a failure
    reason or None), then `offsets` (δ [m], δ' [m/s] per leg). Times are on one clock that
    runs with the walk's slots (`planner.footholds` keeps it)."""

    def __init__(self, legs: Sequence[str], settings: FootholdSettings | None = None) -> None:
        self.legs = tuple(legs)
        self.settings = settings or FootholdSettings()
        self._legs = [_Leg() for _ in self.legs]

    def configure(self, settings: FootholdSettings) -> None:
        """New settings (events from now on use them)."""
        self.settings = settings

    def reset(self, held: Sequence[float] | None = None) -> None:
        """Forget every swing; hold ``held`` [m] per leg (default 0)."""
        values = [0.0] * len(self.legs) if held is None else [float(x) for x in held]
        self._legs = [_Leg(value=v) for v in values]

    def modes(self) -> tuple[Mode, ...]:
        """What each leg's offset does now."""
        return tuple(leg.mode for leg in self._legs)

    def begin_swing(self, i: int, plan: Piecewise, t0: float, swing_time: float,
                    known: tuple[float, float] | None = None) -> None:
        """Leg ``i`` swings from ``t0`` [s] for ``swing_time`` [s] along ``plan`` (its foot
        trajectory in slot time): the held offset blends to 0 until it lowers. (A stop or
        search still running at lift-off, which the timing of a walk does not produce, blends
        from where it would end.) ``known``: the plan's lowering start [s] and foot z at
        touch-down [m] when computed already."""
        leg = self._legs[i]
        t_lower, z_ground = known if known is not None else (
            lowering_start(plan, swing_time), float(plan.evaluate(swing_time)[0][0, 2]))
        leg.swing = _Swing(t0, t0 + t_lower, t0 + swing_time, z_ground, plan)
        value = self.held()[i]
        leg.mode, leg.value, leg.t_start, leg.duration = Mode.BLEND, value, t0, t_lower
        if value == 0.0 or t_lower <= TIME_EPS:
            leg.mode = Mode.HELD  # nothing to blend (or no time to: keep the foothold)

    def replan_swing(self, i: int, plan: Piecewise, t_lower: float) -> None:
        """Leg ``i``'s swing goes on along ``plan`` (same start, end and touch-down) and lowers
        from ``t_lower`` [s] of slot time (a stumble's retry)."""
        swing = self._legs[i].swing
        if swing is not None:
            swing.plan, swing.t_lower = plan, swing.t0 + t_lower

    def quiet(self, now: float) -> bool:
        """True if every offset is 0 and stays 0 without contacts (no blend, stop or search
        running); forgets the swings that have ended by ``now`` [s] (the update's bookkeeping
        when there are no contacts)."""
        quiet = True
        held = Mode.HELD
        for leg in self._legs:
            swing = leg.swing
            if swing is not None and now >= swing.t_end - TIME_EPS:
                leg.swing = None
            leg.pressed = 0
            if leg.mode is not held or leg.value != 0.0:
                quiet = False
        return quiet

    def update(self, now: float, z_plan: Sequence[float],
               contacts: Sequence[FootContact] | None,
               forces: Sequence[float] | None = None) -> str | None:
        """Events at ``now`` [s] from the planned foot z per leg [m] and the
        contact estimate (None: unknown) with its normal forces [N] (None: the touch force
        counts as reached); the reason to end the walk, or None."""
        states = contacts if contacts is not None else (FootContact.UNKNOWN,) * len(self.legs)
        for i, leg in enumerate(self._legs):
            touching = states[i] is FootContact.YES
            pressed = touching and (forces is None or forces[i] >= self.settings.touch_force)
            leg.pressed = leg.pressed + 1 if pressed else 0
            if leg.mode is Mode.BLEND and now >= leg.t_start + leg.duration:
                leg.mode, leg.value = Mode.HELD, 0.0
            if leg.mode is Mode.STOP:
                self._settle(i, now)
                continue
            if leg.mode is Mode.SEARCH:
                if touching:
                    self._begin_stop(i, now, z_plan[i])
                elif now >= leg.t_start + leg.duration:
                    return (f"leg {self.legs[i].upper()} found no ground within the search "
                            f"depth {self.settings.search_depth * 1e3:.1f} mm below its "
                            f"planned touch-down")
                continue
            swing = leg.swing
            if swing is None or leg.mode is not Mode.HELD:
                continue
            if now >= swing.t_end - TIME_EPS:
                leg.swing = None
                if states[i] is FootContact.NO and self.settings.search_depth > 0.0:
                    leg.mode, leg.t_start, leg.ground = Mode.SEARCH, swing.t_end, swing.z_ground
                    leg.duration = self.settings.search_time
            elif (leg.pressed >= EARLY_CONFIRM and now >= swing.t_lower
                  and z_plan[i] + leg.value - swing.z_ground > self.settings.tolerance):
                self._begin_stop(i, now, z_plan[i])
        return None

    def _begin_stop(self, i: int, now: float, z_plan: float) -> None:
        leg = self._legs[i]
        d, dd, ddd = self._state(i, now)
        if leg.swing is not None:
            _, vel, acc = leg.swing.plan.evaluate(now - leg.swing.t0)
            v, a = float(vel[0, 2]), float(acc[0, 2])
            leg.ground = leg.swing.z_ground
        else:
            v = a = 0.0  # after the swing the plan rests on its ground
        s = self.settings
        leg.stop = stop_quintic(z_plan + d, v + dd, a + ddd, s.stop_time)
        leg.mode, leg.t_start, leg.duration = Mode.STOP, now, s.stop_time
        self._settle(i, now)

    def _settle(self, i: int, now: float) -> None:
        """A stop that has ended on a plan that rests on its ground becomes a held offset."""
        leg = self._legs[i]
        if leg.swing is not None and now >= leg.swing.t_end - TIME_EPS:
            leg.swing = None
        if leg.swing is None and now >= leg.t_start + leg.duration:
            z = polynomial(leg.stop, leg.duration)[0]
            leg.mode, leg.value = Mode.HELD, z - leg.ground

    def _state(self, i: int, now: float) -> tuple[float, float, float]:
        """δ, δ', δ'' of a leg that is not stopping, at ``now`` [s]."""
        leg = self._legs[i]
        if leg.mode is Mode.BLEND:
            p, dp, ddp = rest((now - leg.t_start) / leg.duration)
            k = -leg.value
            return (leg.value + k * p, k * dp / leg.duration, k * ddp / leg.duration**2)
        if leg.mode is Mode.SEARCH:
            depth, rate, acc = self.settings.search(now - leg.t_start)
            return (-depth, -rate, -acc)
        return (leg.value, 0.0, 0.0)

    def offsets(self, now: float, z_plan: Sequence[float], zd_plan: Sequence[float]
                ) -> tuple[list[float], list[float]]:
        """δ [m] and δ' [m/s] per leg at ``now`` [s], from the planned foot z [m] and ż [m/s]
        per leg (used by a stopping leg: δ = stop - plan)."""
        out, rate = [], []
        for i, leg in enumerate(self._legs):
            if leg.mode is Mode.STOP:
                q, dq, _ = polynomial(leg.stop, min(now - leg.t_start, leg.duration))
                if now - leg.t_start >= leg.duration:
                    dq = 0.0
                if leg.swing is None or now >= leg.swing.t_end:  # the plan rests on its ground
                    out.append(q - leg.ground)
                    rate.append(dq)
                else:
                    out.append(q - z_plan[i])
                    rate.append(dq - zd_plan[i])
                continue
            d, dd, _ = self._state(i, now)
            out.append(d)
            rate.append(dd)
        for leg, d in zip(self._legs, out, strict=True):
            leg.last = d
        return out, rate

    def held(self) -> np.ndarray:
        """The offsets [m] the legs hold or are heading for (a stop's landing point, 0 for a
        blend, the last offset of a search), for a pose at the end of a slot."""
        values = []
        for leg in self._legs:
            if leg.mode is Mode.STOP:
                z = polynomial(leg.stop, leg.duration)[0]
                values.append(z - leg.ground)
            elif leg.mode is Mode.BLEND:
                values.append(0.0)
            elif leg.mode is Mode.SEARCH:
                values.append(leg.last)
            else:
                values.append(leg.value)
        return np.array(values)
