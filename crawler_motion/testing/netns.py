"""A robot on the other end of a tether, for tests: a Linux network namespace joined to this
one by a veth pair (``ip netns``, ``ip link``; needs root, i.e. CAP_SYS_ADMIN and CAP_NET_ADMIN).

This process and what it starts plainly stay in the host's namespace: the topside. The robot
side lives in a namespace of its own whose only way out is the veth pair, so everything between
the two crosses that link, and `Tether.set_link` can cut it. Inside the robot namespace the
loopback carries multicast (a route for 224.0.0.0/4), so the cross-process CAN bus
(python-can ``udp_multicast``) stays on the robot and never crosses the tether.
`NetnsRecorder` records that bus from a child process that enters the robot namespace.
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import random
import shutil
import signal
import subprocess
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from crawler_motion.testing.bus import BusSpec
from crawler_motion.testing.tap import end_child

#: ``CLONE_NEWNET`` of Linux: the namespace type of ``setns``.
CLONE_NEWNET = 0x40000000
#: Where ``ip netns add`` keeps its namespaces.
NETNS_DIR = "/var/run/netns"


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=check,
                          timeout=10)


def netns_unavailable() -> str | None:
    """Why network namespaces cannot be made here (None when they can): no ``ip`` command,
    not Linux, or no permission (tried with a probe namespace)."""
    if shutil.which("ip") is None:
        return "the `ip` command (iproute2) is not installed"
    if not os.path.isdir("/proc/self/ns"):
        return "not Linux: no network namespaces"
    probe = f"cm_probe_{uuid.uuid4().hex[:8]}"
    made = _ip("netns", "add", probe, check=False)
    if made.returncode != 0:
        return f"cannot create a network namespace ({made.stderr.strip() or 'no permission'})"
    _ip("netns", "del", probe, check=False)
    return None


def enter(netns: str) -> None:
    """Move the calling thread into the named namespace (in a fresh single-threaded child
    process, before it opens any socket, this moves the whole process)."""
    libc = ctypes.CDLL(None, use_errno=True)
    fd = os.open(os.path.join(NETNS_DIR, netns), os.O_RDONLY)
    try:
        if libc.setns(fd, CLONE_NEWNET) != 0:
            errno = ctypes.get_errno()
            raise OSError(errno, f"setns into {netns}: {os.strerror(errno)}")
    finally:
        os.close(fd)


@dataclass
class Tether:
    """The robot's namespace ``robot`` and the veth pair ``host_if`` (here, ``host_ip``) -
    ``robot_if`` (there, ``robot_ip``) on a /30 of 10.x.y.z. `create` makes it, `close`
    removes it (idempotent)."""

    robot: str
    host_if: str
    robot_if: str
    host_ip: str
    robot_ip: str

    @classmethod
    def create(cls) -> Tether:
        """A new robot namespace and its link, up; `OSError` (everything undone) if it fails."""
        tag = uuid.uuid4().hex[:6]
        a, b, c = random.randint(200, 249), random.randint(0, 255), 4 * random.randint(0, 63)
        tether = cls(f"cm_robot_{tag}", f"cmt{tag}", f"cmr{tag}", f"10.{a}.{b}.{c + 1}",
                     f"10.{a}.{b}.{c + 2}")
        try:
            tether._build()
        except (subprocess.CalledProcessError, subprocess.TimeoutExpired) as exc:
            tether.close()
            raise OSError(f"cannot build the tether: {getattr(exc, 'stderr', '') or exc}"
                          ) from exc
        return tether

    def _build(self) -> None:
        ns = self.robot
        _ip("netns", "add", ns)
        _ip("link", "add", self.host_if, "type", "veth", "peer", "name", self.robot_if)
        _ip("link", "set", self.robot_if, "netns", ns)
        _ip("addr", "add", f"{self.host_ip}/30", "dev", self.host_if)
        _ip("-n", ns, "addr", "add", f"{self.robot_ip}/30", "dev", self.robot_if)
        _ip("link", "set", self.host_if, "up")
        _ip("-n", ns, "link", "set", self.robot_if, "up")
        _ip("-n", ns, "link", "set", "lo", "up", "multicast", "on")
        _ip("-n", ns, "route", "add", "224.0.0.0/4", "dev", "lo")

    def command(self, argv: Sequence[str]) -> list[str]:
        """``argv`` run inside the robot's namespace."""
        return ["ip", "netns", "exec", self.robot, *argv]

    def set_link(self, up: bool) -> None:
        """Bring the tether up or down (this side's end of the veth)."""
        _ip("link", "set", self.host_if, "up" if up else "down")

    def close(self) -> None:
        """Remove the link and the namespace (processes still inside keep it alive)."""
        _ip("link", "del", self.host_if, check=False)
        _ip("netns", "del", self.robot, check=False)


def _record_main(netns: str, bus: BusSpec, ready: Any, stop: Any, conn: Any) -> None:
    """Child process: enter ``netns``, record every frame of ``bus`` until ``stop``, then send
    the frames as (kernel receive time [s], id, data) on ``conn``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    enter(netns)
    from crawler_motion.testing.tap import BusTap, FrameRecorder

    recorder = FrameRecorder()
    tap = BusTap(bus.open(), [recorder], timeout=0.1)
    ready.set()
    stop.wait()
    tap.stop()
    conn.send([(t, m.arbitration_id, bytes(m.data)) for t, m in recorder.frames])
    conn.close()


class NetnsRecorder:
    """Every frame of ``bus`` inside namespace ``netns``, recorded by a spawned child process
    (no fork of an rclpy process)."""

    def __init__(self, netns: str, bus: BusSpec) -> None:
        ctx = mp.get_context("spawn")
        self._ready, self._stop = ctx.Event(), ctx.Event()
        self._recv, send = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=_record_main, name="netns-tap", daemon=True,
                                 args=(netns, bus, self._ready, self._stop, send))
        self._proc.start()
        send.close()

    def wait_ready(self, timeout: float) -> bool:
        """True once the child's bus is open."""
        return bool(self._ready.wait(timeout))

    def finish(self, timeout: float = 30.0) -> list[tuple[float, int, bytes]]:
        """Stop recording; the frames (kernel time [s], id, data) in order of reception."""
        self._stop.set()
        if not self._recv.poll(timeout):
            self.kill()
            raise RuntimeError("the bus recorder in the robot's namespace did not report")
        frames: list[tuple[float, int, bytes]] = self._recv.recv()
        self._proc.join(5.0)
        return frames

    def kill(self) -> None:
        """End the child if it still runs."""
        end_child(self._proc, self._stop)
