"""Seabed simulator: MuJoCo model of the crawler in water, range scanner, walk evaluator."""

import ctypes.util
import os

#: The system library each headless GL backend of MuJoCo loads.
_GL_LIBRARIES = {"egl": "EGL", "osmesa": "OSMesa"}
#: Why rendering was switched off at import (its library is missing), else None.
GL_OFF_REASON: str | None = None

# Headless rendering by default; MuJoCo reads this when it is first imported. A headless
# backend whose library is missing would break `import mujoco` itself (PyOpenGL fails on
# import), so rendering is switched off instead and the simulator runs without pictures.
_backend = os.environ.setdefault("MUJOCO_GL", "egl").lower().strip()
if _backend in _GL_LIBRARIES and ctypes.util.find_library(_GL_LIBRARIES[_backend]) is None:
    GL_OFF_REASON = f"MUJOCO_GL={_backend} but lib{_GL_LIBRARIES[_backend]} is not installed"
    os.environ["MUJOCO_GL"] = "disable"

import logging  # noqa: E402  (MuJoCo must be imported after MUJOCO_GL is settled)

import mujoco  # noqa: E402

# MuJoCo appends its warnings (e.g. "the simulation is unstable") to MUJOCO_LOG.TXT in the
# current directory; route them to logging instead (the plant reports instability itself).
mujoco.set_mju_user_warning(lambda text: logging.getLogger("mujoco").warning(text.strip()))
