"""Benchmarks of the motion controller (``make bench``): prints figures, asserts nothing.

Timing: every row calls its function many times after a warm-up, with the garbage collector
disabled while timing, and takes ``time.perf_counter_ns`` around each single call; the table
gives the median and the 99th percentile per call in microseconds (the timer's own overhead,
printed in the header, is not subtracted). The machine may be shared: read the figures as
orders of magnitude, compare rows of one run, and rerun before drawing conclusions.

Rows:

- IK of the 4 legs in one `inverse_kinematics` call, and of a batch of 10,000 foot targets
  (2,500 x 4 legs) in one call;
- re-planning one slot: `GaitSequencer.next_slot` in the steady state (all segment
  coefficients of the slot), and the same followed by `check_trajectories` (what the planner
  does before a slot starts);
- one control tick through the public numpy API: `WalkPlan.evaluate` + `inverse_kinematics`
  + `joint_velocities` for 4 feet / 12 joints at one instant;
- the same tick through `motion.fastpath` (`Track` + `FastKinematics`), and its
  parts; the slot's joints interpolated from its `motion.jointtable.JointTable` (what the
  planner's tick runs on the blind plan) and the table's setup;
- `PlannerCore.tick` while walking at 100 Hz as the node runs it (the next slot planned by
  `PlannerCore.plan_ahead` between ticks), the same without planning ahead (its p99 is the
  slot boundaries, where the tick plans and checks the next slot), and `plan_ahead` itself;
  the same tick with every leg calibrated (synthetic assembly errors: the IK refines each
  leg's last solution with Newton steps, `motion.fastchain`);
- CAN bus load at 1 Mbit/s: commands at 100, 200 and 500 Hz and the feedback at the simulated
  manager's rates, worst-case bit stuffing (`canbus.busload.frame_bits_worst_case`).

- with ``--peer DIR``: StanfordQuadruped's ``Controller.run`` (trot) from its clone, the tick's
  yardstick (`bench_peer`).

Run: crawler-motion bench [--quick] [--config PATH] [--peer DIR]; crawler-motion bench --e2e
[--quick] [...]
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from crawler_motion.model.config import Config, load_config
from crawler_motion.model.kinematics import inverse_kinematics, joint_velocities
from crawler_motion.motion.fastpath import FastKinematics, Track, joint_targets
from crawler_motion.motion.gait import (
    GaitSequencer,
    WalkParams,
    check_trajectories,
    plan_walk,
)
from crawler_motion.motion.jointtable import ANGLE_TOL, RATE_TOL, JointTable
from crawler_motion.tools.bench_peer import (
    CALIBRATED_RATIO,
    PEER_RATIO,
    TICK_TARGET_US,
    PeerError,
    load_peer,
    target_lines,
)
from crawler_motion.tools.bench_planner import (
    PLANNER_RATE,
    calibrated_rows,
    planner_rows,
    side_by_side,
)
from crawler_motion.tools.bench_timing import Row, calls_scaled, measure, timer_overhead

#: Command rates of the bus-load table [Hz] and the bus bit rate [bit/s].
COMMAND_RATES = (100.0, 200.0, 500.0)
BITRATE = 1_000_000.0


def random_targets(cfg: Config, n: int, seed: int = 1) -> np.ndarray:
    """``(n, n_legs, 3)`` reachable foot targets within the limits (around the standing feet)."""
    rng = np.random.default_rng(seed)
    feet = cfg.robot.standing_feet()
    box = np.array([cfg.gait.max_stride / 2, cfg.gait.max_stride / 4, cfg.gait.max_clearance])
    targets = feet + rng.uniform(-1.0, 1.0, (n, *feet.shape)) * box
    targets[..., 2] = np.maximum(targets[..., 2], feet[:, 2])
    inverse_kinematics(cfg.robot, targets)  # all valid, or this raises
    return targets


def ik_rows(cfg: Config, scale: float) -> list[Row]:
    """IK of the 4 legs in one call, and of a batch of 10,000 foot targets."""
    robot = cfg.robot
    feet = random_targets(cfg, 1)[0]
    single = measure("IK, 4 legs in one call (`inverse_kinematics`)",
                     lambda: inverse_kinematics(robot, feet), calls_scaled(5000, scale))
    batch = random_targets(cfg, 2500)
    row = measure("IK, batch of 10,000 foot targets (2,500 x 4) in one call",
                  lambda: inverse_kinematics(robot, batch), calls_scaled(200, scale), warmup=10)
    per = row.median / 10_000 * 1e3 if row.median else math.nan
    return [single, Row(row.name, row.calls, row.median, row.p99, f"{per:.0f} ns per target")]


def replan_rows(cfg: Config, seq: GaitSequencer, scale: float) -> list[Row]:
    """Re-planning one slot in the steady state, without and with `check_trajectories`."""
    for _ in range(3):  # start slot(s), then steady
        seq.next_slot()
    rows = [measure("re-plan one slot (`GaitSequencer.next_slot`, steady)",
                    seq.next_slot, calls_scaled(500, scale), warmup=20)]

    def plan_and_check() -> None:
        slot = seq.next_slot()
        assert slot is not None
        check_trajectories(cfg.robot, slot.legs, "slot")

    rows.append(measure("re-plan one slot + `check_trajectories`", plan_and_check,
                        calls_scaled(300, scale), warmup=10))
    return rows


class PlanClock:
    """Times through a plan at `PLANNER_RATE`, wrapping to 0 after its end [s]."""

    def __init__(self, duration: float) -> None:
        self.duration = duration
        self.t = 0.0

    def __call__(self) -> float:
        self.t += 1.0 / PLANNER_RATE
        if self.t > self.duration:
            self.t = 0.0
        return self.t


def tick_rows(cfg: Config, params: WalkParams, seq: GaitSequencer, scale: float) -> list[Row]:
    """One control tick through the public API and through the fast path, and its parts."""
    robot = cfg.robot
    plan = plan_walk(cfg, params, 3)
    next_time = PlanClock(plan.duration)

    def public_tick() -> None:
        pos, vel, _ = plan.evaluate(next_time())
        q = inverse_kinematics(robot, pos[0])
        joint_velocities(robot, q, vel[0])

    rows = [measure("tick, public API: `WalkPlan.evaluate` + IK + `joint_velocities`",
                    public_tick, calls_scaled(3000, scale),
                    note="4 feet, 12 joints, one instant")]
    evaluator = Track(plan.legs)
    kin = FastKinematics(robot)
    many = calls_scaled(20000, scale)
    rows.append(measure("tick, fast path: `fastpath.joint_targets`",
                        lambda: joint_targets(evaluator, kin, next_time()), many,
                        note="same numbers to 1e-12 (test_fastpath)"))
    pos, vel = evaluator.evaluate(1.3)
    q = kin.inverse(pos)
    rows.append(measure("  fast path part: `Track.evaluate` (4 feet, p + v)",
                        lambda: evaluator.evaluate(next_time()), many))
    rows.append(measure("  fast path part: `FastKinematics.inverse` (4 legs)",
                        lambda: kin.inverse(pos), many))
    rows.append(measure("  fast path part: `FastKinematics.velocities` (12 joints)",
                        lambda: kin.velocities(q, vel), many))
    slot = seq.next_slot()
    assert slot is not None
    rows.append(measure("fast path slot setup (`Track(slot.legs)`)",
                        lambda: Track(slot.legs), calls_scaled(2000, scale)))
    table = JointTable.build(slot.legs, robot)
    assert table is not None
    slot_clock = PlanClock(slot.duration)
    rows.append(measure("tick, joint table: `JointTable.evaluate` (12 joints, p + v)",
                        lambda: table.evaluate(slot_clock()), many,
                        note=f"what the planner's tick runs on the blind plan; "
                             f"{table.n_cells} cells, {table.exact_cells} left to the fast "
                             f"path; within {ANGLE_TOL:g} rad, {RATE_TOL:g} rad/s"))
    rows.append(measure("joint table setup (`JointTable.build`), once per slot",
                        lambda: JointTable.build(slot.legs, robot), calls_scaled(200, scale),
                        note="in the planning thread, with the slot's plan"))
    return rows


def timing_rows(cfg: Config, scale: float) -> list[Row]:
    """Every timing row but the planner's."""
    params = WalkParams.defaults(cfg.gait)
    seq = GaitSequencer(cfg, params)
    return [*ik_rows(cfg, scale), *replan_rows(cfg, seq, scale),
            *tick_rows(cfg, params, seq, scale)]


def bus_rows(cfg: Config) -> list[tuple[str, float, float, int, float]]:
    """(what, rate Hz, frames/s, worst-case bits per cycle, bus load %) rows."""
    from crawler_motion.canbus.busload import frame_bits_worst_case
    from crawler_motion.canbus.protocol import MotorProtocol

    proto = MotorProtocol.from_config(cfg)
    db = proto.database

    def family(kind: str) -> tuple[int, int]:
        ids = proto.frame_ids(kind)
        bits = sum(frame_bits_worst_case(db.get_message_by_frame_id(i).length,
                                         db.get_message_by_frame_id(i).is_extended_frame)
                   for i in ids)
        return len(ids), bits

    rows = []
    n_target, target_bits = family("target")
    for rate in COMMAND_RATES:
        rows.append((f"command: {n_target} target frames", rate, n_target * rate, target_bits,
                     100.0 * target_bits * rate / BITRATE))
    feedback_rate = 1.0 / proto.cycle_period("position")
    heartbeat_rate = 1.0 / proto.cycle_period("heartbeat")
    n_pos, pos_bits = family("position")
    n_eff, eff_bits = family("effort")
    n_stat, stat_bits = family("status")
    n_hb, hb_bits = family("heartbeat")
    bits = pos_bits + eff_bits + stat_bits
    rows.append((f"feedback: {n_pos} position + {n_eff} effort + {n_stat} status frames",
                 feedback_rate, (n_pos + n_eff + n_stat) * feedback_rate, bits,
                 100.0 * bits * feedback_rate / BITRATE))
    rows.append((f"feedback: {n_hb} heartbeat frame", heartbeat_rate, n_hb * heartbeat_rate,
                 hb_bits, 100.0 * hb_bits * heartbeat_rate / BITRATE))
    return rows


def fmt(value: float | None, digits: int = 1) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def print_timing(rows: list[Row], overhead: float) -> None:
    print(f"## Timing (median / p99 per call, us; timer overhead ~{overhead:.2f} us not "
          f"subtracted; GC off while timing)\n")
    print("| what | calls | median [us] | p99 [us] | note |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r.name} | {r.calls} | {fmt(r.median)} | {fmt(r.p99)} | {r.note} |")


def print_bus(rows: list[tuple[str, float, float, int, float]]) -> None:
    print(f"\n## CAN bus load at {BITRATE / 1e6:g} Mbit/s (classic frames, 11-bit ids, "
          f"worst-case bit stuffing incl. interframe space)\n")
    print("| traffic | rate [Hz] | frames/s | worst-case bits per cycle | load [%] |")
    print("|---|---|---|---|---|")
    for what, rate, frames, bits, load in rows:
        print(f"| {what} | {rate:g} | {frames:g} | {bits} | {load:.1f} |")
    feedback = sum(r[4] for r in rows if r[0].startswith("feedback"))
    for what, rate, _, _, load in rows:
        if what.startswith("command"):
            print(f"| **total at {rate:g} Hz command** | | | | **{load + feedback:.1f}** |")
    print("\nMM_Control frames are sent on operator commands only (sporadic) and are not "
          "counted.")


def print_targets(rows: list[Row], pair: tuple[Row, Row] | None, peer_problem: str) -> None:
    """The verdicts: the tick and calibrated rows of the table, the ratio from ``pair`` (the
    tick and the peer side by side; None: ``peer_problem`` says why)."""
    tick = next((r for r in rows if r.name.startswith("planner tick (")), None)
    cal = next((r for r in rows if r.name.startswith("planner tick, calibrated")), None)
    if tick is None or tick.median is None:
        return
    print(f"\n## Targets: planner tick (default walk) <= {TICK_TARGET_US:g} us median and "
          f">= {PEER_RATIO:g}x faster than the peer; calibrated legs <= {CALIBRATED_RATIO:g}x "
          f"the nominal tick\n")
    ours = None if pair is None else pair[0].median
    peer = None if pair is None else pair[1].median
    for line in target_lines(tick.median, tick.p99, None if cal is None else cal.median,
                             peer, peer_problem, ours):
        print(line)


def peer_pair(cfg: Config, path: str | None, scale: float) -> tuple[tuple[Row, Row] | None,
                                                                     str]:
    """The tick and the peer side by side (`bench_planner.side_by_side`), or None and why
    not."""
    if path is None:
        return None, "add it with --peer DIR, a clone of StanfordQuadruped"
    try:
        run = load_peer(path)
    except PeerError as exc:
        return None, str(exc)
    return side_by_side(cfg, run, scale), ""


def bench_e2e(quick: bool, options: list[str]) -> int:
    """End-to-end bench over the cross-process bus (`bench_e2e`): planner -> driver -> CAN,
    the two-node pipeline and the composed ``controller_node`` side by side at 100, 200, 500
    and 1000 Hz, 15 s of walking per rate (5 s with ``--quick``); ``options`` go to
    `bench_e2e.main` (``--seconds`` there overrides the default)."""
    from crawler_motion.tools import bench_e2e as e2e

    return e2e.main(["--seconds", "5" if quick else "15", *options])


def main(argv: list[str] | None = None) -> int:
    """Run the benchmarks and print the tables."""
    parser = argparse.ArgumentParser(prog="crawler-motion bench",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="10x fewer calls per row (a smoke run; figures are noisier)")
    parser.add_argument("--config", default=None, help="robot.yaml (default: the shipped one)")
    parser.add_argument("--e2e", action="store_true",
                        help="end-to-end bench over the cross-process bus instead (further "
                             "options: crawler-motion bench --e2e --help)")
    parser.add_argument("--peer", default=None, metavar="DIR",
                        help="a clone of StanfordQuadruped: time its Controller.run (trot) in "
                             "this process beside the planner tick (needs transforms3d)")
    args, rest = parser.parse_known_args(argv)
    if args.e2e:
        return bench_e2e(args.quick, rest)
    if rest:
        parser.error(f"unrecognized arguments: {' '.join(rest)}")
    cfg = load_config(args.config)
    scale = 0.1 if args.quick else 1.0
    print(f"# crawler_motion bench (Python {sys.version.split()[0]}, numpy {np.__version__})\n")
    overhead = timer_overhead()
    rows = timing_rows(cfg, scale)
    rows.extend(planner_rows(cfg, scale))
    rows.extend(calibrated_rows(cfg, scale))
    pair, peer_problem = peer_pair(cfg, args.peer, scale)
    print_timing(rows if pair is None else [*rows, *pair], overhead)
    print_targets(rows, pair, peer_problem)
    print_bus(bus_rows(cfg))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
