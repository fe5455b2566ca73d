"""The ROS parameters that open the CAN bus, shared by the driver and the seabed simulator."""

from __future__ import annotations

import can
from can.interfaces.udp_multicast import UdpMulticastBus

from crawler_motion.runtime.parameters import ParamSpec, not_empty


def _python_can_interface(value: str) -> str | None:
    if value in can.VALID_INTERFACES:
        return None
    return (f"can_interface {value!r} is not a python-can interface; use one of "
            f"{sorted(can.VALID_INTERFACES)}")


BUS_PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("can_interface", "udp_multicast",
              "python-can interface: udp_multicast (cross-process on loopback), socketcan "
              "(vcan0 / can0), virtual (in-process), ...", read_only=True,
              check=_python_can_interface),
    ParamSpec("can_channel", UdpMulticastBus.DEFAULT_GROUP_IPv4,
              "bus channel: multicast group for udp_multicast, interface name for socketcan",
              read_only=True, check=not_empty),
    ParamSpec("can_port", 0, "UDP port of udp_multicast; 0 = the interface default (43113)",
              read_only=True, minimum=0, maximum=65535),
)
