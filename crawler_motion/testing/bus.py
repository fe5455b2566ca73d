"""Where a cross-process test bus lives: interface, channel and a free UDP port."""

from __future__ import annotations

import random
import socket
from dataclasses import dataclass
from typing import Any

from crawler_motion.canbus.bus import (
    UDP_MULTICAST,
    default_channel,
    describe_bus,
    make_bus_factory,
)

#: python-can's default IPv4 group of ``udp_multicast``.
DEFAULT_GROUP = str(default_channel(UDP_MULTICAST))


#: Ports ``free_udp_port`` draws from: above the privileged ports and below both the RTPS port
#: base of DDS (7400; every ROS domain's ports are 7400 + 250 domain + offsets) and the
#: kernel's ephemeral range (32768-60999 by default). A port drawn from the ephemeral range
#: could be free when drawn and be bound by a DDS participant of the test's own domain (or by
#: any socket bound to port 0) before the stack's processes bind it.
FREE_PORTS = (1024, 7399)


def free_udp_port(attempts: int = 64) -> int:
    """A UDP port in `FREE_PORTS` that no socket holds right now (one per cross-process bus:
    sockets bind the port). Raises ``OSError`` if ``attempts`` draws all find a port held."""
    for _ in range(attempts):
        port = random.randint(*FREE_PORTS)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                s.bind(("", port))
            except OSError:
                continue
            return port
    raise OSError(f"no free UDP port in {FREE_PORTS[0]}-{FREE_PORTS[1]} after {attempts} draws")


def random_multicast_group() -> str:
    """A random IPv4 multicast group in 239.0.0.0/8 (administratively scoped)."""
    return f"239.{random.randint(1, 254)}.{random.randint(1, 254)}.{random.randint(1, 254)}"


@dataclass(frozen=True)
class BusSpec:
    """One bus as every process of a stack opens it (``port`` only for ``udp_multicast``)."""

    interface: str = UDP_MULTICAST
    channel: str = DEFAULT_GROUP
    port: int = 0

    @classmethod
    def fresh(cls, interface: str = UDP_MULTICAST, channel: str | None = None) -> BusSpec:
        """A bus of its own: for ``udp_multicast`` a free port (and the default group unless
        ``channel`` is given); otherwise ``channel`` (default ``vcan0``)."""
        if interface == UDP_MULTICAST:
            return cls(interface, channel or DEFAULT_GROUP, free_udp_port())
        return cls(interface, channel or default_channel(interface) or "vcan0", 0)

    @property
    def udp(self) -> bool:
        """True for the cross-process ``udp_multicast`` bus."""
        return self.interface == UDP_MULTICAST

    def cli_args(self) -> list[str]:
        """Options of ``motor_manager_sim`` that open this bus."""
        args = ["--interface", self.interface, "--channel", self.channel]
        return [*args, "--port", str(self.port)] if self.udp else args

    def ros_params(self) -> dict[str, Any]:
        """Parameters of ``driver_node`` that open this bus."""
        params: dict[str, Any] = {"can_interface": self.interface, "can_channel": self.channel}
        if self.udp:
            params["can_port"] = self.port
        return params

    def open(self) -> Any:
        """A python-can bus on it (``udp_multicast``: not receiving its own frames); python-can's
        errors pass through."""
        return make_bus_factory(self.interface, self.channel, self.port, bitrate=None)()

    def __str__(self) -> str:
        return describe_bus(self.interface, self.channel, self.port)
