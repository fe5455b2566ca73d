"""The process stack launcher and bus tap shared by the demo, benchmarks and tests."""

from crawler_motion.testing.bus import BusSpec, free_udp_port, random_multicast_group
from crawler_motion.testing.stack import (
    STACK_COMMAND_TIMEOUT,
    StackProcesses,
    StackSpec,
    isolated_env,
    random_domain,
)
from crawler_motion.testing.tap import BusTap, FamilyCounter, FrameRecorder

__all__ = ["STACK_COMMAND_TIMEOUT", "BusSpec", "BusTap", "FamilyCounter", "FrameRecorder",
           "StackProcesses", "StackSpec", "free_udp_port", "isolated_env", "random_domain",
           "random_multicast_group"]
