"""Pictures of a walk, rendered headless (skipped where no GL backend works)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from crawler_motion.errors import ConfigError
from crawler_motion.motion.gait import WalkParams
from crawler_motion.sim.seabed.model import SeabedModel
from crawler_motion.sim.seabed.render import (
    RECORD_STEM,
    CameraSettings,
    gif_stride,
    gl_unavailable,
    record_paths,
    render_snapshots,
    render_walk,
)

REASON = gl_unavailable()


@pytest.mark.skipif(REASON is not None, reason=str(REASON))
def test_walk_is_rendered_to_png_and_gif(cfg, tmp_path):
    png, gif = tmp_path / "walk.png", tmp_path / "walk.gif"
    written = render_walk(cfg, WalkParams.defaults(cfg.gait), 1, png, gif,
                          camera=CameraSettings(width=160, height=120, fps=4.0))
    assert written == [png, gif]
    picture = np.asarray(Image.open(png))
    assert picture.shape == (120, 160, 3)
    assert picture.std() > 5.0  # a scene, not a blank image
    with Image.open(gif) as animation:
        assert animation.n_frames >= 8  # 2.4 s of walk at 4 frames/s


@pytest.mark.parametrize("kwargs", [{"width": 8}, {"fps": 0.0}, {"distance": -1.0}])
def test_bad_camera_settings_are_refused(kwargs):
    with pytest.raises(ConfigError):
        CameraSettings(**kwargs)


@pytest.mark.skipif(REASON is not None, reason=str(REASON))
def test_kept_states_are_rendered_after_the_run(cfg, tmp_path):
    sm = SeabedModel(cfg.robot)
    data = sm.make_data()
    states = []
    for k in range(30):  # the body moves 1 cm per state
        data.qpos[0] = 0.01 * k
        states.append(data.qpos.copy())
    png, gif = tmp_path / "out" / "run.png", tmp_path / "out" / "run.gif"
    written = render_snapshots(sm, states, 20.0, png, gif,
                               CameraSettings(width=160, height=120))
    assert written == [png, gif]
    assert np.asarray(Image.open(png)).shape == (120, 160, 3)
    with Image.open(gif) as animation:
        assert animation.n_frames == 15  # 20 states/s kept, at most 10 frames/s shown
        assert animation.info["duration"] == 100


def test_rendering_no_states_is_refused(cfg, tmp_path):
    with pytest.raises(ValueError, match="no states"):
        render_snapshots(SeabedModel(cfg.robot), [], 10.0, tmp_path / "a.png",
                         tmp_path / "a.gif")


@pytest.mark.parametrize(("frames", "fps", "stride"), [
    (1, 10.0, 1), (150, 10.0, 1), (151, 10.0, 2), (300, 10.0, 2), (301, 10.0, 3),
    (100, 10.5, 2), (100, 20.0, 2), (100, 30.0, 3), (100, 0.5, 1),
])
def test_gif_stride_keeps_the_animation_small(frames, fps, stride):
    assert gif_stride(frames, fps) == stride
    assert -(-frames // stride) <= 150 and fps / stride <= 10.0


def test_record_paths_of_a_prefix_and_of_a_directory(tmp_path):
    assert record_paths(tmp_path / "walk") == (tmp_path / "walk.png", tmp_path / "walk.gif")
    assert record_paths(f"{tmp_path}/new/") == (tmp_path / "new" / f"{RECORD_STEM}.png",
                                                tmp_path / "new" / f"{RECORD_STEM}.gif")
    assert record_paths(tmp_path) == (tmp_path / f"{RECORD_STEM}.png",
                                      tmp_path / f"{RECORD_STEM}.gif")
    assert record_paths("a.b") == (Path("a.b.png"), Path("a.b.gif"))


@pytest.mark.parametrize("value", ["disable", "off", "0"])
def test_rendering_switched_off_is_said_in_one_line(monkeypatch, value):
    monkeypatch.setenv("MUJOCO_GL", value)
    reason = gl_unavailable()
    assert reason == f"no GL backend for pictures: rendering is off (MUJOCO_GL={value})"
