"""Shared fixtures of the seabed simulator tests."""

from __future__ import annotations

import os

import pytest

# MuJoCo picks its GL backend when first imported: headless EGL unless the caller chose one.
os.environ.setdefault("MUJOCO_GL", "egl")

pytest.importorskip("mujoco", reason="the seabed simulator needs the mujoco package")

from crawler_motion.model.config import Config, load_config


@pytest.fixture(scope="session")
def cfg() -> Config:
    """The shipped configuration."""
    return load_config()
