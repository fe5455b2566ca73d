"""The end-to-end bench's targets, judged against the machine's floor measured in the same run.

A 2-vCPU virtual machine skips deadlines and wakes threads late whatever runs on it, so the
timing targets are relative to the floor (`wake_floor`: a bare ticker process at the same rate
for the same window, just before the pipelines): a pipeline may skip at most
`Target.extra_skipped_per_10s` deadlines per 10 s more than the floor did, and its p99 period
error may exceed the floor's by at most `Target.extra_p99_ms`. Latency and CPU bounds are
absolute. `print_against_floor` prints each run beside its floor with the ratios and the
verdict of its target.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import TYPE_CHECKING

from crawler_motion.tools.e2e_analysis import fmt

if TYPE_CHECKING:  # pragma: no cover
    from crawler_motion.tools.bench_e2e import RateResult
    from crawler_motion.tools.wake_floor import Floor


class Pipeline(str, Enum):
    """How the planner and the driver run: two processes, or composed in one."""

    TWO_NODE = "two-node"
    CONTROLLER = "controller"


@dataclass(frozen=True)
class Target:
    """What a pipeline must reach at one rate; a bound of None is not judged.

    ``extra_skipped_per_10s``: deadlines the planner's ticker skipped, beyond the floor's,
    per 10 s of window; ``extra_p99_ms``: p99 period error above the floor's [ms];
    ``p99_latency_ms``: JointState -> CAN frame [ms]; ``cpu_ms_per_command``: planner +
    driver CPU per command at the achieved rate [ms]; ``min_rate`` achieved [Hz];
    ``max_cpu_percent``: planner + driver [% of one core].
    """

    extra_skipped_per_10s: float | None = 2.0
    extra_p99_ms: float | None = 0.25
    p99_latency_ms: float | None = None
    cpu_ms_per_command: float | None = None
    min_rate: float | None = None
    max_cpu_percent: float | None = None

    def bounds(self) -> list[str]:
        """The bounds as text (those judged)."""
        return [text.format(value) for name, text in BOUND_TEXT
                if (value := getattr(self, name)) is not None]


#: How each bound of a `Target` reads ({:g}: its value), in the order they are printed.
BOUND_TEXT = (("extra_skipped_per_10s", "deadlines skipped <= floor + {:g} per 10 s"),
              ("extra_p99_ms", "p99 period error <= floor + {:g} ms"),
              ("p99_latency_ms", "JointState->CAN p99 <= {:g} ms"),
              ("cpu_ms_per_command", "CPU <= {:g} ms per command"),
              ("min_rate", ">= {:g} Hz achieved"),
              ("max_cpu_percent", "CPU <= {:g} % of a core"))


#: The targets per (pipeline, rate [Hz]).
TARGETS: dict[tuple[Pipeline, float], Target] = {
    (Pipeline.TWO_NODE, 500.0): Target(p99_latency_ms=1.5, cpu_ms_per_command=0.6),
    (Pipeline.CONTROLLER, 500.0): Target(p99_latency_ms=0.5, cpu_ms_per_command=0.35),
    (Pipeline.CONTROLLER, 1000.0): Target(None, None, min_rate=990.0, max_cpu_percent=40.0),
}


def chain_cpu(result: RateResult) -> float:
    """CPU of planner + driver (the two processes, or the one controller) [% of one core]."""
    c = result.cpu
    if result.pipeline is Pipeline.CONTROLLER:
        return c.get("controller", math.nan)
    return c.get("planner", math.nan) + c.get("driver", math.nan)


def cpu_per_command(result: RateResult) -> float:
    """Planner + driver CPU per command at the achieved rate [ms]."""
    rate = result.timing.rate if result.timing is not None else result.rate
    return 10.0 * chain_cpu(result) / rate


def allowed_skips(target: Target, floor: Floor | None, seconds: float) -> float:
    """Deadlines the target allows to skip in a window of ``seconds`` [s] (inf: not judged)."""
    if target.extra_skipped_per_10s is None or floor is None:
        return math.inf
    return floor.skipped + target.extra_skipped_per_10s * seconds / 10.0


def shortfalls(result: RateResult, target: Target, floor: Floor | None,
               seconds: float) -> list[str]:
    """What ``result`` misses of ``target`` against ``floor`` (empty when it is met; the
    floor's bounds are not judged without a floor)."""
    t = result.timing
    if t is None:
        return [f"failed: {result.error}"]
    out = []
    allowed = allowed_skips(target, floor, seconds)
    if result.skipped > allowed:
        out.append(f"{result.skipped} deadlines skipped (floor {floor.skipped if floor else '-'}"
                   f", allowed {allowed:g})")
    if target.extra_p99_ms is not None and floor is not None and not (
            t.err_p99_ms <= floor.timing.err_p99_ms + target.extra_p99_ms):
        out.append(f"p99 period error {t.err_p99_ms:.3f} ms (floor "
                   f"{floor.timing.err_p99_ms:.3f} ms)")
    if target.p99_latency_ms is not None and not result.lat_p99_ms <= target.p99_latency_ms:
        out.append(f"p99 latency {result.lat_p99_ms:.2f} ms")
    if target.cpu_ms_per_command is not None and not (
            cpu_per_command(result) <= target.cpu_ms_per_command):
        out.append(f"CPU {cpu_per_command(result):.2f} ms per command")
    if target.min_rate is not None and not t.rate >= target.min_rate:
        out.append(f"achieved {t.rate:.1f} Hz")
    if target.max_cpu_percent is not None and not chain_cpu(result) <= target.max_cpu_percent:
        out.append(f"CPU {chain_cpu(result):.0f} %")
    return out + ([result.error] if result.error else [])


def _ratio(value: float, floor: float) -> str:
    return f"{value / floor:.1f}x" if floor > 0 and math.isfinite(value) else "-"


def against_floor_row(result: RateResult, floor: Floor | None, seconds: float) -> str:
    """One row of `print_against_floor`."""
    target = TARGETS.get((result.pipeline, result.rate))
    t = result.timing
    if t is None:
        return f"| {result.pipeline.value} | {result.rate:g} | failed: {result.error} | | | | |"
    if floor is None:
        skips = f"{result.skipped} / - / -"
        p99 = f"{fmt(t.err_p99_ms, 3)} / - / -"
    else:
        skips = (f"{result.skipped} / {floor.skipped} / "
                 f"{result.skipped - floor.skipped:+d}")
        p99 = (f"{fmt(t.err_p99_ms, 3)} / {fmt(floor.timing.err_p99_ms, 3)} / "
               f"{_ratio(t.err_p99_ms, floor.timing.err_p99_ms)}, "
               f"{t.err_p99_ms - floor.timing.err_p99_ms:+.3f}")
    if target is None:
        verdict = "no target at this rate"
    else:
        why = shortfalls(result, target, floor, seconds)
        verdict = "**met**" if not why else "**NOT met**: " + "; ".join(why)
    return (f"| {result.pipeline.value} | {result.rate:g} | {skips} | {p99} | "
            f"{fmt(result.lat_p99_ms, 2)} | {fmt(cpu_per_command(result), 2)} "
            f"({fmt(chain_cpu(result), 0)} %) | {verdict} |")


def print_against_floor(results: Sequence[RateResult], floors: Mapping[float, Floor],
                        seconds: float) -> bool:
    """Each run beside the floor of its rate, the ratios, and its target's verdict; the
    targets; True when every judged target is met."""
    print(f"\n## Against the floor ({seconds:g} s windows; the floor is a bare ticker process "
          f"at the same rate, measured just before)\n")
    print("| pipeline | rate [Hz] | deadlines skipped: run / floor / difference | p99 period "
          "error [ms]: run / floor / ratio, difference | JointState->CAN p99 [ms] | CPU ms "
          "per command (% of a core) | verdict |")
    print("|---|---|---|---|---|---|---|")
    met = True
    for r in results:
        print(against_floor_row(r, floors.get(r.rate), seconds))
        target = TARGETS.get((r.pipeline, r.rate))
        if target is not None:
            met = met and not shortfalls(r, target, floors.get(r.rate), seconds)
    print("\nTargets: " + "; ".join(f"{p.value} at {rate:g} Hz: {', '.join(t.bounds())}"
                                    for (p, rate), t in TARGETS.items()) + ".")
    return met
