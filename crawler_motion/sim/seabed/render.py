"""Pictures of a walk: a camera following the body, a final PNG and an animated GIF (headless).

A replayed walk is rendered as it runs (`render_walk`); a live run keeps only its states and
renders them afterwards (`render_snapshots`), so pictures cost the run nothing.

MuJoCo renders off-screen through the GL backend named by ``MUJOCO_GL`` (``egl`` by default,
set by this subpackage; ``osmesa`` needs ``libosmesa6``). `gl_unavailable` says in one line why
no picture can be made, so callers can go on without pictures.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np
from PIL import Image

from crawler_motion.model.config import Config
from crawler_motion.motion.gait import WalkParams, plan_walk
from crawler_motion.sim.seabed import GL_OFF_REASON
from crawler_motion.sim.seabed.model import SeabedModel, SimSettings
from crawler_motion.sim.seabed.replay import ReplayOptions, replay
from crawler_motion.sim.seabed.water import check_range

#: Limits of an animation of a recorded run: frames and frame rate [Hz] (a small GIF).
MAX_GIF_FRAMES = 150
MAX_GIF_FPS = 10.0
#: File stem of the pictures when the record target is a directory.
RECORD_STEM = "seabed_walk"


@dataclass(frozen=True)
class CameraSettings:
    """Image size [px], frame rate [Hz] and the following camera's distance [m] and angles
    (azimuth, elevation [deg], MuJoCo's free-camera convention)."""

    width: int = 640
    height: int = 480
    fps: float = 10.0
    distance: float = 0.7
    azimuth: float = 135.0
    elevation: float = -25.0

    def __post_init__(self) -> None:
        check_range("width", self.width, 16, 1280, "px")
        check_range("height", self.height, 16, 960, "px")
        check_range("fps", self.fps, 1e-3, 100.0, "Hz")
        check_range("distance", self.distance, 0.05, 100.0, "m")


def gl_unavailable() -> str | None:
    """None when off-screen rendering works, else one line saying why not."""
    if GL_OFF_REASON is not None:
        return f"no GL backend for pictures: {GL_OFF_REASON}"
    backend = os.environ.get("MUJOCO_GL", "default")
    if backend.lower().strip() in ("disable", "disabled", "off", "false", "0"):
        return f"no GL backend for pictures: rendering is off (MUJOCO_GL={backend})"
    try:
        model = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
        with mujoco.Renderer(model, 16, 16) as renderer:
            renderer.render()
    except Exception as exc:  # any backend failure means: no pictures
        return f"no GL backend for pictures (MUJOCO_GL={backend}): {exc}".splitlines()[0]
    return None


class FollowCamera:
    """Renders frames from a free camera that keeps the robot's body in the centre."""

    def __init__(self, sm: SeabedModel, settings: CameraSettings | None = None) -> None:
        self.sm = sm
        self.settings = settings or CameraSettings()
        s = self.settings
        self.renderer = mujoco.Renderer(sm.model, s.height, s.width)
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.camera.distance, self.camera.azimuth = s.distance, s.azimuth
        self.camera.elevation = s.elevation
        self.frames: list[np.ndarray] = []
        self._next = 0.0

    def frame(self, data: mujoco.MjData) -> np.ndarray:
        """Render the current state, looking at the body."""
        self.camera.lookat[:] = data.xpos[self.sm.base_body]
        self.renderer.update_scene(data, self.camera)
        return self.renderer.render().copy()

    def __call__(self, data: mujoco.MjData) -> None:
        """Keep a frame every 1 / fps of simulated time (use as a replay observer)."""
        if data.time + 1e-9 >= self._next:
            self.frames.append(self.frame(data))
            self._next = data.time + 1.0 / self.settings.fps

    def save_png(self, path: str | Path, data: mujoco.MjData) -> Path:
        """Write the current state as a PNG."""
        out = Path(path)
        Image.fromarray(self.frame(data)).save(out)
        return out

    def save_gif(self, path: str | Path) -> Path:
        """Write the kept frames as an animated GIF (looping, at the frame rate)."""
        if not self.frames:
            raise ValueError("no frames kept: run a replay with this camera as observer first")
        out = Path(path)
        images = [Image.fromarray(f).quantize(colors=128) for f in self.frames]
        images[0].save(out, save_all=True, append_images=images[1:], loop=0,
                       duration=round(1000.0 / self.settings.fps))
        return out

    def close(self) -> None:
        """Release the GL context (explicitly: do not leave it to the garbage collector)."""
        self.renderer.close()

    def __enter__(self) -> FollowCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


#: The camera of a recorded run (a small GIF).
RECORD_CAMERA = CameraSettings(width=480, height=360)


def record_paths(target: str | Path) -> tuple[Path, Path]:
    """The PNG and GIF of a record target: a directory (existing, or written with a trailing
    slash) gets ``seabed_walk.png`` / ``.gif`` in it, anything else is a path prefix."""
    text = str(target)
    base = Path(text)
    if text.endswith(("/", os.sep)) or base.is_dir():
        base = base / RECORD_STEM
    return base.with_name(base.name + ".png"), base.with_name(base.name + ".gif")


def gif_stride(frames: int, fps: float, max_frames: int = MAX_GIF_FRAMES,
               max_fps: float = MAX_GIF_FPS) -> int:
    """Keep every n-th of ``frames`` taken at ``fps`` [Hz] so the animation has at most
    ``max_frames`` frames and ``max_fps`` frames per second of simulated time."""
    return max(1, math.ceil(frames / max_frames), math.ceil(fps / max_fps - 1e-9))


def render_snapshots(sm: SeabedModel, snapshots: Sequence[np.ndarray], fps: float,
                     png: str | Path, gif: str | Path,
                     camera: CameraSettings | None = None) -> list[Path]:
    """Render states (``qpos`` taken every 1 / ``fps`` [Hz]) after a run: the last one as a
    PNG, every `gif_stride`-th as an animated GIF; returns the files (parents created)."""
    if not snapshots:
        raise ValueError("no states recorded")
    stride = gif_stride(len(snapshots), fps)
    settings = replace(camera or RECORD_CAMERA, fps=fps / stride)
    data = mujoco.MjData(sm.model)
    for path in (png, gif):
        Path(path).parent.mkdir(parents=True, exist_ok=True)
    with FollowCamera(sm, settings) as cam:
        for qpos in snapshots[::stride]:
            data.qpos[:] = qpos
            mujoco.mj_forward(sm.model, data)
            cam.frames.append(cam.frame(data))
        data.qpos[:] = snapshots[-1]
        mujoco.mj_forward(sm.model, data)
        return [cam.save_png(png, data), cam.save_gif(gif)]


def render_walk(cfg: Config, params: WalkParams, steps: int, png: str | Path | None,
                gif: str | Path | None, settings: SimSettings | None = None,
                world: str | Path | None = None, camera: CameraSettings | None = None,
                options: ReplayOptions | None = None) -> list[Path]:
    """Replay a planned walk and write its final picture and animation; returns the files.

    Raises `RuntimeError` with `gl_unavailable`'s line when pictures cannot be made.
    """
    reason = gl_unavailable()
    if reason is not None:
        raise RuntimeError(reason)
    plan = plan_walk(cfg, params, steps)
    sm = SeabedModel(cfg.robot, settings, world)
    data = sm.make_data(plan.joints(np.zeros(1))[0][0])
    written = []
    with FollowCamera(sm, camera) as cam:
        replay(sm, plan, options, data, observer=cam if gif is not None else None)
        if png is not None:
            written.append(cam.save_png(png, data))
        if gif is not None:
            written.append(cam.save_gif(gif))
    return written
