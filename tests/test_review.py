"""Review tools: recordings hold what they should, rendered frames are not blank, MP4s decode."""

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cpp_mujoco.maps import load_map
from cpp_mujoco.review.recording import MissionRecorder
from cpp_mujoco.review.rendering import RenderingError, VideoWriter, configure_gl

RERUN = str(Path(sys.executable).parent / "rerun")


def rrd_entities(path) -> dict[str, set[str]]:
    """Entity path → archetypes logged there, read back with ``rerun rrd print``, after
    ``rerun rrd verify`` has accepted the file."""
    verify = subprocess.run([RERUN, "rrd", "verify", str(path)], capture_output=True, text=True)
    assert verify.returncode == 0, verify.stderr
    out = subprocess.run(
        [RERUN, "rrd", "print", "-v", str(path)], capture_output=True, text=True, check=True
    ).stdout
    entities: dict[str, set[str]] = {}
    for entity, columns in re.findall(r" - (/\S+) - data columns: \[(.*)\]", out):
        entities.setdefault(entity, set()).update(re.findall(r"@(\w+):", columns))
    return entities


def test_recording_verifies_and_holds_images_lines_scalars_transforms(tmp_path):
    grid_map = load_map("B")
    path = tmp_path / "mission.rrd"
    rec = MissionRecorder(path, grid_map)
    footprint = np.array([[-6.0, -6.0], [6.0, -6.0], [6.0, 6.0], [-6.0, 6.0]])
    for step in range(3):
        t = 3.0 * step
        rec.log_pose(t, [step, 0.0, 6.0], (1, 0, 0, 0), footprint + step)
        rec.log_camera(t, np.full((24, 32, 3), 40 * step, dtype=np.uint8))
        rec.log_pose(t + 1.5, [step + 0.5, 0.0, 6.0])
        info = {
            "budget": 30 - step,
            "coverage_ratio": 0.1 * step,
            "rejected": False,
            "position": (14, 3),
            "landed": step == 2,
            "energy_used_j": 100.0 * step,
        }
        rec.log_step(t + 3.0, 1, -0.2, info, np.zeros(256, bool), 14 * 16 + 3)
    rec.close()
    entities = rrd_entities(path)
    assert "Transform3D" in entities["/world/uav"]
    assert "LineStrips3D" in entities["/world/trajectory"]
    assert "LineStrips3D" in entities["/world/footprint"]
    assert "EncodedImage" in entities["/camera/image"]  # JPEG-compressed onboard frames
    assert "Image" in entities["/coverage"]
    assert "Boxes3D" in entities["/world/ground"] and "Boxes3D" in entities["/world/no_fly"]
    for metric in ("energy_j", "budget", "reward", "return", "coverage_ratio"):
        assert "Scalars" in entities[f"/metrics/{metric}"]
    assert any(e.startswith("/view") or e == "/viewport" for e in entities)  # the blueprint


def test_unwritable_recording_path_is_a_clear_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OSError, match="cannot write recording"):
        MissionRecorder(blocker / "m.rrd", load_map("A"))


_RENDER_SCRIPT = """
import numpy as np, sys
import cpp_mujoco
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.maps import load_map
from cpp_mujoco.review.rendering import OffscreenCamera
import mujoco
model = compile_arena(build_arena(load_map("B"), PhysicsConfig()))
data = mujoco.MjData(model)
mujoco.mj_forward(model, data)
cam = OffscreenCamera(model, camera="quadrotor/downward")
data.qpos[:3] = (0.0, 0.0, 6.0)
mujoco.mj_forward(model, data)
frame = cam.render(data)
cam.close()
np.save(sys.argv[1], frame)
"""


@pytest.mark.parametrize("backend", ["egl", "osmesa"])
def test_rendered_frame_is_not_blank(tmp_path, backend):
    out = tmp_path / "frame.npy"
    env = {**os.environ, "MUJOCO_GL": backend}
    env.pop("PYOPENGL_PLATFORM", None)
    result = subprocess.run(
        [sys.executable, "-c", _RENDER_SCRIPT, str(out)], env=env, capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr[-2000:]
    frame = np.load(out)
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    assert frame.std() > 10
    assert len(np.unique(frame.reshape(-1, 3) // 32, axis=0)) >= 3  # several zones in view


def test_mp4_decodes(tmp_path):
    import imageio.v3 as iio

    path = tmp_path / "v.mp4"
    with VideoWriter(path, fps=10) as video:
        for i in range(12):
            frame = np.zeros((240, 320, 3), dtype=np.uint8)
            frame[:, : 20 * (i + 1)] = (200, 50, 50)
            video.write(frame)
    frames = iio.imread(path)
    assert frames.shape[0] == 12 and frames.shape[1:] == (240, 320, 3)
    assert frames[-1].mean() > frames[0].mean()


def test_unknown_gl_backend():
    with pytest.raises(RenderingError, match="unknown GL backend"):
        configure_gl("vulkan")
