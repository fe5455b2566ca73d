"""Records of the end-to-end runs: growable float tables and target frame groups from a bus tap."""

from __future__ import annotations

import math
import multiprocessing as mp
import signal
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from crawler_motion.testing.tap import FAMILIES, FamilyCounter, end_child

#: Columns of a target frame group (see `GroupRecorder`): kernel time, user time, counter,
#: frames, then the joint positions.
GROUP_T, GROUP_T_USER, GROUP_COUNTER, GROUP_FRAMES, GROUP_Q = 0, 1, 2, 3, 4
#: Columns of a recorded JointState: header stamp, receive time (time.time()), positions.
REC_STAMP, REC_RECV, REC_Q = 0, 1, 2
#: Period of the live counters a `TapProcess` publishes [s].
PUBLISH_PERIOD = 0.25


class Rows:
    """A growable float table filled row by row (chunked: appending never copies)."""

    def __init__(self, width: int, chunk: int = 16_384) -> None:
        self.width = width
        self._chunk = chunk
        self._chunks: list[np.ndarray] = []
        self._n = 0

    def __len__(self) -> int:
        return self._n

    def append(self) -> np.ndarray:
        """A fresh row (a view, NaN-filled) to fill in place."""
        i = self._n % self._chunk
        if i == 0:
            self._chunks.append(np.empty((self._chunk, self.width)))
        self._n += 1
        row = self._chunks[-1][i]
        row.fill(math.nan)
        return row

    def array(self) -> np.ndarray:
        """A copy of the rows filled so far, shape ``(n, width)``."""
        if not self._chunks:
            return np.empty((0, self.width))
        return np.concatenate(self._chunks)[: self._n].copy()


class GroupRecorder(FamilyCounter):
    """`FamilyCounter` that also decodes the target frames into one row per tick (`Rows`).

    Row: kernel receive time of the first frame (SO_TIMESTAMPNS on the listener's socket,
    CLOCK_REALTIME), ``time.time()`` when the listener thread got it, counter, number of
    frames seen, 12 joint positions in joint order (NaN where a frame was not seen). A frame
    starts a new group when its counter differs from the current group's or its id is already
    in it.
    """

    def __init__(self, protocol: Any, joint_names: Sequence[str]) -> None:
        super().__init__(protocol)
        self.protocol = protocol
        self.index = {name: i for i, name in enumerate(joint_names)}
        self.groups = Rows(GROUP_Q + len(joint_names))
        self.undecodable = 0
        self._row: np.ndarray | None = None
        self._ids: set[int] = set()

    def on_message_received(self, msg: Any) -> None:
        super().on_message_received(msg)
        if self.kind(msg) == "target":
            self._target(msg)

    def _target(self, msg: Any) -> None:
        from crawler_motion.canbus.protocol import TargetFrame

        try:
            frame = self.protocol.decode(msg)
        except Exception:
            self.undecodable += 1
            return
        if not isinstance(frame, TargetFrame):
            return
        row = self._row
        if row is None or frame.counter != row[GROUP_COUNTER] or msg.arbitration_id in self._ids:
            row = self._row = self.groups.append()
            row[GROUP_T] = msg.timestamp
            row[GROUP_T_USER] = time.time()
            row[GROUP_COUNTER] = frame.counter
            row[GROUP_FRAMES] = 0
            self._ids = set()
        self._ids.add(msg.arbitration_id)
        row[GROUP_FRAMES] += 1
        for joint, value in frame.positions.items():
            row[GROUP_Q + self.index[joint]] = value

def _tap_main(port: int, shared: Any, ready: Any, stop: Any, conn: Any) -> None:
    """Child process: run a `GroupRecorder` until ``stop``, then send its records on ``conn``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops us (Ctrl-C goes to all)
    from crawler_motion.canbus.protocol import MotorProtocol
    from crawler_motion.model.config import load_config
    from crawler_motion.testing.bus import UDP_MULTICAST, BusSpec
    from crawler_motion.testing.tap import BusTap

    cfg = load_config()
    recorder = GroupRecorder(MotorProtocol.from_config(cfg.robot), cfg.robot.joint_names)
    tap = BusTap(BusSpec(UDP_MULTICAST, port=port).open(), [recorder], timeout=0.1)
    ready.set()

    def publish() -> None:
        for i, kind in enumerate(FAMILIES):
            shared[i] = recorder.counts.get(kind, 0)
        shared[len(FAMILIES)] = len(recorder.groups)

    while not stop.wait(PUBLISH_PERIOD):
        publish()
    tap.stop()
    publish()
    conn.send({"counts": dict(recorder.counts), "groups": recorder.groups.array(),
               "undecodable": recorder.undecodable})
    conn.close()


@dataclass
class TapResult:
    """What the bus listener saw: frames per family and the target frame groups."""

    counts: dict[str, int]
    groups: np.ndarray
    undecodable: int


class TapProcess:
    """A `GroupRecorder` on the bus in a child process (spawned: no fork of an rclpy process)."""

    def __init__(self, port: int) -> None:
        ctx = mp.get_context("spawn")
        self._shared = ctx.Array("q", len(FAMILIES) + 1, lock=False)
        self._ready = ctx.Event()
        self._stop = ctx.Event()
        self._recv, send = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=_tap_main, name="bus-tap", daemon=True,
                                 args=(port, self._shared, self._ready, self._stop, send))
        self._proc.start()
        send.close()

    @property
    def pid(self) -> int:
        """Process id of the listener."""
        return int(self._proc.pid or 0)

    def wait_ready(self, timeout: float) -> bool:
        """True once the listener's bus is open."""
        return bool(self._ready.wait(timeout))

    def counts(self) -> tuple[dict[str, int], int]:
        """Live frames per family and target groups (updated every 0.25 s)."""
        values = list(self._shared)
        return dict(zip(FAMILIES, values, strict=False)), int(values[len(FAMILIES)])

    def finish(self, timeout: float = 30.0) -> TapResult:
        """Stop listening and collect the records."""
        self._stop.set()
        if not self._recv.poll(timeout):
            self.kill()
            raise RuntimeError("the bus listener did not report back")
        data = self._recv.recv()
        self._proc.join(5.0)
        return TapResult(data["counts"], data["groups"], data["undecodable"])

    def kill(self) -> None:
        """End the listener if it is still running."""
        end_child(self._proc, self._stop)

