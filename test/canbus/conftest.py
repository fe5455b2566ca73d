"""Fixtures of the canbus tests: the shipped robot and its protocol."""

from __future__ import annotations

import pytest

from crawler_motion.canbus.protocol import MotorProtocol
from crawler_motion.model.config import load_config


@pytest.fixture(scope="module")
def robot():
    return load_config().robot


@pytest.fixture(scope="module")
def proto(robot):
    return MotorProtocol.from_config(robot)
