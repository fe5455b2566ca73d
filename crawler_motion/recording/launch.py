"""Command lines of the recorder and the report for a stack started by `testing.stack`."""

from __future__ import annotations

import sys
from pathlib import Path

from crawler_motion.testing.bus import BusSpec


def cli_command() -> list[str]:
    """The ``crawler-motion`` CLI next to this interpreter, else ``python -m``."""
    script = Path(sys.executable).parent / "crawler-motion"
    return [str(script)] if script.exists() else [sys.executable, "-m",
                                                  "crawler_motion.tools.cli"]


def record_command(mcap: Path, bus: BusSpec | None = None, can_log: Path | None = None,
                   quiet: bool = True) -> list[str]:
    """``crawler-motion record`` into ``mcap``; with ``bus`` and ``can_log`` it also logs
    that bus."""
    cmd = [*cli_command(), "record", "-o", str(mcap)]
    if bus is not None and can_log is not None:
        cmd += ["--can-log", str(can_log), "--interface", bus.interface, "--channel",
                bus.channel, "--port", str(bus.port)]
    return [*cmd, "--quiet"] if quiet else cmd
