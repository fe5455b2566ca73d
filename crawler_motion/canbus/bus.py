"""Opening a python-can bus from the package's interface/channel/port/bitrate settings."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import can
from can.interfaces.udp_multicast import UdpMulticastBus

from crawler_motion.errors import BusOpenError

#: The python-can interface of the cross-process bus on one machine.
UDP_MULTICAST = "udp_multicast"
#: Bit rate of the motor-manager bus [bit/s].
DEFAULT_BITRATE = 1_000_000
#: Interfaces whose bit rate python-can does not set (socketcan's is set with ``ip link``).
NO_BITRATE = frozenset({"virtual", "socketcan", UDP_MULTICAST})
#: Errors python-can raises when a bus cannot be opened.
OPEN_ERRORS = (can.CanError, OSError, ValueError, ImportError, NotImplementedError)


def default_channel(interface: str) -> str | None:
    """The channel used when none is given: python-can's IPv4 group for ``udp_multicast``,
    ``vcan0`` for ``socketcan``, None (must be given) for every other interface."""
    if interface == UDP_MULTICAST:
        return str(UdpMulticastBus.DEFAULT_GROUP_IPv4)
    if interface == "socketcan":
        return "vcan0"
    return None


def bus_kwargs(interface: str, channel: str, port: int = 0,
               bitrate: int | None = DEFAULT_BITRATE) -> dict[str, Any]:
    """Keyword arguments of ``can.Bus``: ``udp_multicast`` does not receive its own frames and
    takes ``port`` when non-zero; ``bitrate`` [bit/s] goes to interfaces that set it (not when
    None)."""
    kwargs: dict[str, Any] = {"interface": interface, "channel": channel}
    if interface == UDP_MULTICAST:
        kwargs["receive_own_messages"] = False
        if port:
            kwargs["port"] = int(port)
    elif interface not in NO_BITRATE and bitrate is not None:
        kwargs["bitrate"] = int(bitrate)
    return kwargs


def describe_bus(interface: str, channel: str, port: int = 0) -> str:
    """The bus in words, e.g. ``udp_multicast 239.74.163.2:43113`` or ``socketcan vcan0``."""
    return f"{interface} {channel}" + (f":{port}" if interface == UDP_MULTICAST else "")


def make_bus_factory(interface: str, channel: str, port: int = 0,
                     bitrate: int | None = DEFAULT_BITRATE) -> Callable[[], can.BusABC]:
    """A factory opening the bus anew on every call; python-can's errors pass through."""
    kwargs = bus_kwargs(interface, channel, port, bitrate)

    def factory() -> can.BusABC:
        return can.Bus(**kwargs)

    return factory


def open_bus(interface: str, channel: str, port: int = 0,
             bitrate: int | None = None) -> can.BusABC:
    """Open the bus once; a failure raises `BusOpenError` naming the bus (`describe_bus`)."""
    try:
        return make_bus_factory(interface, channel, port, bitrate)()
    except OPEN_ERRORS as exc:
        # python-can warns "... was not properly shut down" when a half-built bus is collected
        logging.getLogger("can.bus").setLevel(logging.ERROR)
        raise BusOpenError(f"cannot open the CAN bus {describe_bus(interface, channel, port)}: "
                           f"{exc}", interface=interface, channel=channel, port=port) from exc
