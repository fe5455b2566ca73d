"""Checks a bring-up makes before it starts anything: every one raises `ConfigError` with one
line naming what is wrong and why, so a bad option leaves nothing running."""

from __future__ import annotations

import errno
import socket
from pathlib import Path

from crawler_motion.errors import ConfigError
from crawler_motion.testing.bus import BusSpec


def check_world(world: str) -> None:
    """The world file loads (a shipped name or an MJCF path)."""
    from crawler_motion.sim.seabed.world import load_world, worlds_dir

    path = Path(world)
    if not path.suffix and not path.exists() and not (worlds_dir() / f"{world}.xml").exists():
        shipped = sorted(p.stem for p in worlds_dir().glob("*.xml"))
        raise ConfigError(f"unknown world {world!r}: give a shipped world ({', '.join(shipped)})"
                          " or the path of an MJCF file")
    load_world(world)


def check_output(path: Path, what: str) -> None:
    """``path`` can be written: its directory exists and is a directory."""
    parent = Path(path).resolve().parent
    if not parent.is_dir():
        raise ConfigError(f"{what} {path}: its directory {parent} does not exist")
    if Path(path).is_dir():
        raise ConfigError(f"{what} {path}: is a directory; give a file name")


def check_port_free(host: str, port: int, what: str) -> None:
    """Nothing listens on TCP ``host:port`` yet."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind((host, port))
        except OSError as exc:
            reason = "in use" if exc.errno == errno.EADDRINUSE else exc.strerror
            raise ConfigError(f"{what}: port {port} on {host} {reason}; choose another "
                              "with --view-port") from exc


def check_bus(bus: BusSpec) -> None:
    """The CAN bus opens (and is closed again at once)."""
    try:
        opened = bus.open()
    except Exception as exc:
        raise ConfigError(f"CAN bus {bus}: cannot open it ({exc})") from exc
    opened.shutdown()
