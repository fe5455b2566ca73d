"""Session-wide test settings: an isolated ROS graph per test session."""

from __future__ import annotations

import os
import random
from collections.abc import Iterator

import pytest

# Before any rclpy import: keep parallel sessions on this machine from hearing each other.
os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(1, 101)))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
# MuJoCo picks its GL backend when first imported, whichever test imports it first: headless.
os.environ.setdefault("MUJOCO_GL", "egl")


@pytest.fixture()
def ros_domain() -> Iterator[int]:
    """rclpy up in a ROS domain of its own for one test (the stack's processes join it)."""
    import rclpy

    domain = random.randint(102, 200)
    rclpy.init(domain_id=domain)
    try:
        yield domain
    finally:
        rclpy.try_shutdown()
