"""``crawler-motion soak --mission FILE``: options, the run, the Markdown report and the verdict.

Targets (issue "reliability"): 0 collisions (hull or leg contacts with an obstacle; a leg
link brushing the seabed is reported, the walk's), 0 motions during a fault, 100 %
recoveries, RSS growth of every process that lived through it ≤ `RSS_GROWTH` after the warm-up
(5 minutes, or the first third of a shorter run), the recording opened by ``mcap`` and
``rosbags``. Exit 0 when every target is met, 1 when one is not, 2 on bad options.

Run: ``make soak-mission`` (30 minutes, ≥ 20 faults); the test suite runs 3 minutes.
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from crawler_motion.errors import CrawlerMotionError
from crawler_motion.runtime.cli_args import OneLineParser, finite_number
from crawler_motion.tools.fault_plan import fault_plan
from crawler_motion.tools.mission_soak import MissionSoak, SoakResult, open_checks

PROG = "crawler-motion soak --mission"
#: Largest RSS growth of a process after the warm-up (share of its size then).
RSS_GROWTH = 0.10
#: Warm-up before the RSS reference sample [s] (a shorter run: its first third).
WARMUP = 300.0


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    """The options (``--mission`` given)."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--mission", type=Path, required=True, help="the mission file (YAML)")
    parser.add_argument("--world", default="harbour", help="seabed world (default harbour)")
    parser.add_argument("--duration", type=finite_number("duration", positive=True),
                        default=1800.0, help="soak time [s] (default 1800)")
    parser.add_argument("--faults", type=int, default=100,
                        help="most faults injected (default: as many as fit)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the fault plan")
    parser.add_argument("--quiet", type=finite_number("quiet", positive=True), nargs=2,
                        default=None, metavar=("LOW", "HIGH"),
                        help="walking between faults [s] (default 15 45)")
    parser.add_argument("--record", type=Path, default=None, metavar="RUN.mcap",
                        help="the recording (default: in the logs directory)")
    parser.add_argument("--logs", type=Path, default=None,
                        help="the processes' logs (default: a new temporary directory)")
    return parser.parse_args(argv)


def report(result: SoakResult, checks: dict[str, str], warmup: float) -> list[str]:
    """Print the Markdown report; the failed targets."""
    print("\n## Faults\n\n| soak time [s] | fault | length [s] | still after [s] "
          "| hold required within [s] | moved during it [mm] | recovery | recovered after [s] "
          "| result |\n|---|---|---|---|---|---|---|---|---|")
    for r in result.faults:
        print(f"| {r.at:.0f} | {r.name} | {r.length:g} | {_f(r.held_after)} | "
              f"{f'{r.hold_within:g}' if r.hold else 'no'} | {1000 * r.moved:.1f} | "
              f"{r.recovery} | {_f(r.recovered_after)} | {'ok' if r.ok else 'FAILED'}"
              f"{' (' + '; '.join(r.notes) + ')' if r.notes else ''} |")
    growth = rss_growth(result, warmup)
    print("\n## Memory (RSS, MB)\n")
    for at, sample in result.rss:
        print(f"- {at:.0f} s: " + ", ".join(f"{k} {v:.0f}" for k, v in sorted(sample.items())))
    print("\nGrowth after the warm-up: " + (", ".join(
        f"{k} {100 * g:+.1f} %" for k, g in sorted(growth.items())) or "no process sampled "
        "twice after the warm-up"))
    print(f"\nMissions done: {result.missions_done}; unexpected mission failures: "
          f"{len(result.unexpected)} {result.unexpected or ''}; hull or leg contact ticks with "
          f"an obstacle: {result.obstacle_contacts}, in all: {result.contacts} "
          f"({result.first_contacts or 'none'}); recording: "
          + ", ".join(f"{k} {v}" for k, v in checks.items()))
    failures = []
    if result.obstacle_contacts:
        failures.append(f"{result.obstacle_contacts} obstacle contact ticks")
    if bad := [r.name for r in result.faults if not r.ok]:
        failures.append(f"faults not handled: {', '.join(bad)}")
    if result.unexpected:
        failures.append(f"{len(result.unexpected)} mission failures without a fault")
    if grown := [k for k, g in growth.items() if g > RSS_GROWTH]:
        failures.append(f"RSS grew > {100 * RSS_GROWTH:.0f} %: {', '.join(grown)}")
    if failed := [k for k, v in checks.items() if v.startswith(("failed", "not installed"))]:
        failures.append(f"recording not read by {', '.join(failed)}")
    return failures


def rss_growth(result: SoakResult, warmup: float) -> dict[str, float]:
    """Growth of RSS of each process (name@pid) from its first sample after ``warmup`` [s] to
    its last (processes sampled at least twice then)."""
    firsts: dict[str, float] = {}
    lasts: dict[str, float] = {}
    counts: dict[str, int] = {}
    for at, sample in result.rss:
        if at < warmup:
            continue
        for key, value in sample.items():
            firsts.setdefault(key, value)
            lasts[key] = value
            counts[key] = counts.get(key, 0) + 1
    return {k: lasts[k] / firsts[k] - 1.0 for k in firsts if counts[k] >= 2 and firsts[k] > 0}


def _f(value: float | None) -> str:
    return "never" if value is None else f"{value:.2f}"


def main(argv: Sequence[str]) -> int:
    """Run the mission soak; the exit status."""
    import rclpy

    from crawler_motion.navigation.mission import parse_mission
    from crawler_motion.tools.live_nav import LiveNav

    args = parse_args(argv)
    try:
        text = args.mission.read_text(encoding="utf-8")
        parse_mission(text)
    except (OSError, CrawlerMotionError) as exc:
        print(f"{PROG}: error: {args.mission}: {exc}", file=sys.stderr)
        return 2
    quiet = tuple(args.quiet) if args.quiet else (15.0, 45.0)
    plan = fault_plan(args.seed, args.faults, quiet)
    logs = args.logs or Path(tempfile.mkdtemp(prefix="mission-soak-"))
    record = args.record or logs / "soak.mcap"
    domain = random.randint(102, 200)
    rclpy.init(domain_id=domain)
    began = time.monotonic()

    def say(line: str) -> None:
        print(f"[{time.monotonic() - began:7.1f} s] {line}", flush=True)

    nav = LiveNav(logs, args.world, domain=domain, record=record, split=True)
    try:
        say(f"soak: {args.duration:g} s of missions ({args.mission}) in {args.world}, faults "
            f"from seed {args.seed}; logs in {logs}")
        nav.start()
        result = MissionSoak(nav, text, args.seed, say).run(plan, args.duration)
    except (RuntimeError, CrawlerMotionError) as exc:
        print(f"{PROG}: error: {exc}\n{nav.tails()}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    finally:
        nav.close()
        rclpy.try_shutdown()
    failures = report(result, open_checks(record), min(WARMUP, args.duration / 3.0))
    if failures:
        print("\n**FAILED**: " + "; ".join(failures))
        return 1
    print(f"\n**PASSED**: {len(result.faults)} faults, every one held, still and recovered; "
          "no contact; memory flat; the recording opens")
    return 0
