"""Opening a python-can bus from the package's interface/channel/port/bitrate settings."""

from __future__ import annotations

import ctypes
import logging
import socket
import struct
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
                     bitrate: int | None = DEFAULT_BITRATE, *,
                     own_frames: bool = True) -> Callable[[], can.BusABC]:
    """A factory opening the bus anew on every call; python-can's errors pass through.

    ``own_frames=False``: a ``udp_multicast`` bus does not receive the frames it sends
    (`drop_own_frames`), as a SocketCAN socket does not by default."""
    kwargs = bus_kwargs(interface, channel, port, bitrate)

    def factory() -> can.BusABC:
        bus = can.Bus(**kwargs)
        if not own_frames and interface == UDP_MULTICAST:
            drop_own_frames(bus)
        return bus

    return factory


#: ``SO_ATTACH_FILTER`` of Linux (``socket`` does not export it).
SO_ATTACH_FILTER = 26


def drop_own_frames(bus: can.BusABC) -> bool:
    """Make a python-can ``udp_multicast`` bus (IPv4) stop receiving its own frames; True if
    done, False where it cannot be (another interface or python-can version, not Linux).

    The kernel loops every multicast datagram back to each member socket, the sender's own
    included, so python-can's ``udp_multicast`` receives what it sends (its
    ``receive_own_messages=False`` is not enforced), unlike a SocketCAN socket
    (``CAN_RAW_RECV_OWN_MSGS`` is off by default). Each sent frame then also costs a wake-up and
    a decode on the receiving side. Here the bus sends through a second socket on a port of its
    own, and a classic BPF filter on the receiving socket drops datagrams from that UDP source
    port (a UDP socket filter sees the UDP header at offset 0); every other member still gets
    them.
    """
    multicast = getattr(bus, "_multicast", None)
    rx = getattr(multicast, "_socket", None)
    if rx is None or rx.family != socket.AF_INET or not hasattr(multicast, "send"):
        return False
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL,
                      rx.getsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL))
        tx.bind(("", 0))
        port = tx.getsockname()[1]
        # ldh [0] (UDP source port); jeq port ? drop : accept whole datagram
        code = b"".join(struct.pack("HBBI", *ins) for ins in (
            (0x28, 0, 0, 0), (0x15, 0, 1, port), (0x06, 0, 0, 0), (0x06, 0, 0, 0xFFFFFFFF)))
        program = ctypes.create_string_buffer(code)
        rx.setsockopt(socket.SOL_SOCKET, SO_ATTACH_FILTER,
                      struct.pack("HL", len(code) // 8, ctypes.addressof(program)))
    except OSError:
        tx.close()
        return False
    destination = (multicast.group, multicast.port)
    timeouts: list[float | None] = [None]  # the one set on ``tx`` (setting it costs syscalls)

    def send(data: bytes, timeout: float | None = None) -> None:
        if timeout != timeouts[0]:
            tx.settimeout(timeout)
            timeouts[0] = timeout
        try:
            if tx.sendto(data, destination) < len(data):
                raise can.CanTimeoutError()
        except TimeoutError:
            raise can.CanTimeoutError() from None
        except OSError as error:
            raise can.CanOperationError("failed to send via socket") from error

    close = multicast.shutdown

    def shutdown() -> None:
        tx.close()
        close()

    multicast.send, multicast.shutdown = send, shutdown
    return True


def open_bus(interface: str, channel: str, port: int = 0,
             bitrate: int | None = None, *, own_frames: bool = True) -> can.BusABC:
    """Open the bus once; a failure raises `BusOpenError` naming the bus (`describe_bus`).
    ``own_frames``: see `make_bus_factory`."""
    try:
        return make_bus_factory(interface, channel, port, bitrate, own_frames=own_frames)()
    except OPEN_ERRORS as exc:
        # python-can warns "... was not properly shut down" when a half-built bus is collected
        logging.getLogger("can.bus").setLevel(logging.ERROR)
        raise BusOpenError(f"cannot open the CAN bus {describe_bus(interface, channel, port)}: "
                           f"{exc}", interface=interface, channel=channel, port=port) from exc
