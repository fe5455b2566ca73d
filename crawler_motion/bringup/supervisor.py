"""Start a lineup in order, watch it, stop it: the process side of a bring-up.

`Supervisor.start` starts the members stage by stage, a stage once the stages before it are
ready (every member's ROS nodes on the graph, as the ``ready`` callable sees them), each process
logging to ``<logs>/<name>.log``, and reports each with ``on_ready(name, pid, seconds)``.
`Supervisor.exited` names the first member that ended; `Supervisor.restart` starts one again
(a soak's fault injection), `Supervisor.send` signals one.
`Supervisor.stop` sends SIGINT to every process still running, the last started first (the
navigator before the controller, the controller before the simulated motors), waits for each,
and SIGKILLs what is left after a timeout, so nothing stays behind.
"""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from crawler_motion.bringup.lineup import Member
from crawler_motion.errors import CrawlerMotionError

#: Polling period of readiness and watching [s].
POLL = 0.05


class BringUpError(CrawlerMotionError):
    """A member did not come up: it exited, or its nodes did not appear in time."""

    def __init__(self, member: str, reason: str, tail: Sequence[str] = ()) -> None:
        super().__init__(f"{member}: {reason}")
        self.member, self.reason, self.tail = member, reason, list(tail)


@dataclass(frozen=True)
class Exit:
    """A member that ended: its name, pid and exit status."""

    name: str
    pid: int
    status: int


class Supervisor:
    """The processes of one bring-up."""

    def __init__(self, logs: Path, env: Mapping[str, str],
                 ready: Callable[[Sequence[str]], bool]) -> None:
        self.logs, self.env, self.ready = Path(logs), dict(env), ready
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self.members: dict[str, Member] = {}

    def log_path(self, name: str) -> Path:
        """The log file of member ``name``."""
        return self.logs / f"{name}.log"

    def tail(self, name: str, lines: int = 12) -> list[str]:
        """The last ``lines`` lines of the log of ``name``."""
        path = self.log_path(name)
        if not path.exists():
            return []
        return path.read_text(errors="replace").splitlines()[-lines:]

    def start(self, members: Sequence[Member], timeout: float,
              on_ready: Callable[[str, int, float], None]) -> None:
        """Start ``members`` stage by stage (a stage once every member before it is ready:
        its nodes seen within ``timeout`` [s]); `BringUpError` when one exits or stays
        invisible."""
        self.logs.mkdir(parents=True, exist_ok=True)
        for stage in sorted({m.stage for m in members}):
            began = time.monotonic()
            waiting = [m for m in members if m.stage == stage]
            for member in waiting:
                self._launch(member)
            while waiting:
                for member in [m for m in waiting if self.ready(m.nodes)]:
                    waiting.remove(member)
                    on_ready(member.name, self.procs[member.name].pid,
                             time.monotonic() - began)
                for member in waiting:
                    self._check_alive(member, began, timeout)
                if waiting:
                    time.sleep(POLL)
            time.sleep(max((m.settle for m in members if m.stage == stage), default=0.0))

    def restart(self, name: str, timeout: float) -> float:
        """Start member ``name`` again (after it ended) with its command line, its log
        appended to; wait until its nodes are seen (`BringUpError` after ``timeout`` [s]).
        Returns the time it took [s]."""
        member = self.members[name]
        if self.procs[name].poll() is None:
            raise BringUpError(name, "still running: stop it before a restart")
        began = time.monotonic()
        self._launch(member, mode="ab")
        while not self.ready(member.nodes):
            self._check_alive(member, began, timeout)
            time.sleep(POLL)
        return time.monotonic() - began

    def send(self, name: str, sig: int) -> None:
        """Send ``sig`` to member ``name`` (its process group), if it still runs."""
        _signal(self.procs[name], sig)

    def _launch(self, member: Member, mode: str = "wb") -> None:
        self.members[member.name] = member
        with open(self.log_path(member.name), mode) as log:
            self.procs[member.name] = subprocess.Popen(
                list(member.command), stdout=log, stderr=subprocess.STDOUT, env=self.env,
                start_new_session=True, preexec_fn=functools.partial(_prepare_child,
                                                                     member.nice))

    def _check_alive(self, member: Member, began: float, timeout: float) -> None:
        proc = self.procs[member.name]
        if proc.poll() is not None:
            raise BringUpError(member.name, f"exited with status {proc.returncode} while "
                               "starting", self.tail(member.name))
        if time.monotonic() - began > timeout:
            raise BringUpError(member.name, f"its nodes {list(member.nodes)} did not appear "
                               f"within {timeout:g} s", self.tail(member.name))

    def exited(self) -> Exit | None:
        """The first member found ended, else None."""
        for name, proc in self.procs.items():
            if proc.poll() is not None:
                return Exit(name, proc.pid, int(proc.returncode))
        return None

    def running(self) -> list[str]:
        """Members still running, in start order."""
        return [n for n, p in self.procs.items() if p.poll() is None]

    def stop_one(self, name: str, timeout: float = 2.0) -> None:
        """SIGINT member ``name`` and wait for it (SIGKILL after ``timeout`` [s])."""
        proc = self.procs[name]
        _signal(proc, signal.SIGINT)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            _signal(proc, signal.SIGKILL)
            proc.wait()

    def stop(self, timeout: float = 2.5) -> list[str]:
        """SIGINT every running member (last started first), wait up to ``timeout`` [s] in
        all, SIGKILL the rest; returns the names that had to be killed."""
        order = list(reversed(self.procs))
        for name in order:
            if self.procs[name].poll() is None:
                _signal(self.procs[name], signal.SIGINT)
        end = time.monotonic() + timeout
        killed = []
        for name in order:
            proc = self.procs[name]
            try:
                proc.wait(max(0.0, end - time.monotonic()))
            except subprocess.TimeoutExpired:
                _signal(proc, signal.SIGKILL)
                proc.wait()
                killed.append(name)
        return killed


@contextlib.contextmanager
def interrupts_held() -> Iterator[None]:
    """Ctrl-C (SIGINT) ignored inside the block, when called from the main thread: stopping
    the processes must not be cut short by a second Ctrl-C (that would orphan some). The
    previous handler is restored after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _prepare_child(nice: int) -> None:
    """In the child before exec: raise its niceness by ``nice``; SIGTERM when the bring-up
    dies, even by SIGKILL (Linux ``PR_SET_PDEATHSIG``), so no process outlives it."""
    import ctypes

    if nice:
        os.nice(nice)
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except (OSError, AttributeError):  # not Linux: the SIGINT/SIGKILL of `stop` remain
        pass


#: ``prctl`` option of Linux: the signal a child gets when its parent dies.
PR_SET_PDEATHSIG = 1


def _signal(proc: subprocess.Popen[bytes], sig: int) -> None:
    """Send ``sig`` to the process group of ``proc`` (its children too), if still there."""
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass
