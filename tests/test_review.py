"""Review tools: recordings hold what they should, rendered frames are not blank, MP4s decode."""

import os
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from cpp_mujoco.maps import load_map
from cpp_mujoco.physics.view.rendering import RenderingError, VideoWriter, configure_gl
from cpp_mujoco.review.recording import MissionRecorder

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


def rrd_print(path, verbosity: str = "-vvv") -> str:
    """Everything ``rerun rrd print`` shows (data included at -vvv)."""
    return subprocess.run(
        [RERUN, "rrd", "print", verbosity, str(path)], capture_output=True, text=True, check=True
    ).stdout


def rrd_stores(path) -> set[tuple[str, str]]:
    """(application id, recording id) of every recording store in the file."""
    return set(re.findall(r'Recording,\s*"([^"]+)",\s*"([^"]+)"', rrd_print(path, "-v")))


def rrd_num_chunks(path) -> int:
    out = subprocess.run([RERUN, "rrd", "stats", str(path)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return int(re.search(r"num_chunks = ([\d ]+)", out.stdout).group(1).replace(" ", ""))


def _log_mission(rec: MissionRecorder, steps: int) -> None:
    footprint = np.array([[-6.0, -6.0], [6.0, -6.0], [6.0, 6.0], [-6.0, 6.0]])
    for step in range(steps):
        t = 3.0 * step
        rec.log_pose(t, [step, 0.0, 6.0], (1, 0, 0, 0), footprint + step)
        rec.log_camera(t, np.full((24, 32, 3), 40 * (step % 6), dtype=np.uint8))
        rec.log_pose(t + 1.5, [step + 0.5, 0.0, 6.0])
        info = {
            "budget": 30 - step,
            "coverage_ratio": 0.1 * step,
            "rejected": False,
            "position": (14, 3),
            "landed": step == steps - 1,
            "energy_used_j": 100.0 * step,
        }
        rec.log_step(t + 3.0, 1, -0.2, info, np.zeros(256, bool), 14 * 16 + 3)


def test_recording_verifies_and_holds_images_lines_scalars_transforms(tmp_path):
    grid_map = load_map("B")
    path = tmp_path / "mission.rrd"
    rec = MissionRecorder(path, grid_map)
    _log_mission(rec, 3)
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


def test_each_recording_has_its_own_id_and_a_readable_application_id(tmp_path):
    # before: every recording had the recording id "mission", so two opened together merged
    ids = set()
    for name in ("one.rrd", "two.rrd"):
        rec = MissionRecorder(tmp_path / name, load_map("C"))
        _log_mission(rec, 1)
        rec.close()
        stores = rrd_stores(tmp_path / name)
        assert {app for app, _ in stores} == {"cpp_mujoco"}
        ids |= {rid for _, rid in stores}
    assert len(ids) == 2 and "mission" not in ids


def test_a_mission_is_written_in_few_chunks(tmp_path):
    # before: a flush after every step gave ~7 chunks per step (1,006 for one mission)
    path = tmp_path / "long.rrd"
    rec = MissionRecorder(path, load_map("B"))
    _log_mission(rec, 60)
    rec.close()
    chunks = rrd_num_chunks(path)
    assert chunks <= 45, chunks  # blueprint and static scene ~25, then one chunk per entity


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
from cpp_mujoco.physics.view.rendering import OffscreenCamera
from cpp_mujoco.physics.view.scenery import Scenery
import mujoco
model = compile_arena(build_arena(load_map("B"), PhysicsConfig()))
data = mujoco.MjData(model)
mujoco.mj_forward(model, data)
cam = OffscreenCamera(model, camera="quadrotor/downward", decorate=Scenery.from_model(model))
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
    video = VideoWriter(path, fps=10)
    for i in range(12):
        frame = np.zeros((240, 320, 3), dtype=np.uint8)
        frame[:, : 20 * (i + 1)] = (200, 50, 50)
        video.write(frame)
    assert video.close() == path
    frames = iio.imread(path)
    assert frames.shape[0] == 12 and frames.shape[1:] == (240, 320, 3)
    assert frames[-1].mean() > frames[0].mean()


def test_unknown_gl_backend():
    with pytest.raises(RenderingError, match="unknown GL backend"):
        configure_gl("vulkan")


def _frames(n: int):
    for i in range(n):
        frame = np.zeros((240, 320, 3), dtype=np.uint8)
        frame[:, : 20 * (i % 16 + 1)] = (200, 50, 50)
        yield frame


def test_video_appears_under_its_name_only_when_complete(tmp_path):
    path = tmp_path / "v.mp4"
    video = VideoWriter(path, fps=10)
    for frame in _frames(5):
        video.write(frame)
    assert not path.exists()  # being written to a hidden temporary file
    assert video.close() == path
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.mp4"]


def test_interrupted_video_is_finalised_as_partial(tmp_path):
    import imageio.v3 as iio

    path = tmp_path / "v.mp4"
    video = VideoWriter(path, fps=10)
    for frame in _frames(6):
        video.write(frame)
    assert (
        video.close(partial=True) == tmp_path / "v.partial.mp4"
    )  # what an interrupted mission does
    assert not path.exists()  # never passes for the complete video
    assert iio.imread(tmp_path / "v.partial.mp4").shape[0] == 6  # but plays
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.partial.mp4"]


@pytest.mark.parametrize("disk_full", [False, True])
def test_ffmpeg_failure_is_one_line_and_leaves_no_temporary_file(tmp_path, monkeypatch, disk_full):
    from cpp_mujoco.util.io import WriteError

    path = tmp_path / "v.mp4"
    path.write_bytes(b"previous video")
    video = VideoWriter(path, fps=10)
    video.write(next(_frames(1)))
    video._writer._write_gen.gi_frame.f_locals["p"].kill()  # ffmpeg dies, as on a full disk
    if disk_full:
        full = SimpleNamespace(f_bavail=0, f_bfree=0)  # what a full disk reports
        monkeypatch.setattr(os, "statvfs", lambda _: full)
    with pytest.raises(WriteError) as info:
        for frame in _frames(200):  # the broken pipe shows within a few frames
            video.write(frame)
        video.close()
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    if disk_full:
        assert "no space left on device" in message
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.mp4"]
    assert path.read_bytes() == b"previous video"  # the previous file is untouched


def test_figure_on_a_full_disk_is_a_write_error_and_leaves_nothing(tmp_path, monkeypatch):
    import errno

    from matplotlib.figure import Figure

    from cpp_mujoco.review.plots import map_figure
    from cpp_mujoco.util.io import WriteError

    path = tmp_path / "map.png"
    path.write_bytes(b"previous figure")

    def full_disk(self, fname, **kwargs):
        Path(fname).write_bytes(b"\x89PNG half")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", full_disk)
    with pytest.raises(WriteError, match="no space left on device"):
        map_figure(load_map("C"), path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.png"]
    assert path.read_bytes() == b"previous figure"


def test_a_video_without_its_index_is_recognised(tmp_path):
    """ffmpeg's exit status is not checked by imageio: a video cut before its index (full disk
    while finalising) must be caught by looking for the index itself."""
    from cpp_mujoco.physics.view.rendering import VideoWriter, _has_index

    writer = VideoWriter(tmp_path / "v.mp4", fps=10)
    for i in range(5):
        writer.write(np.full((64, 64, 3), 40 * i, dtype=np.uint8))
    path = writer.close()
    assert _has_index(path)
    cut = tmp_path / "cut.mp4"
    data = path.read_bytes()
    cut.write_bytes(data[: data.index(b"moov") - 4])
    assert not _has_index(cut)


def _log_windy_mission(rec: MissionRecorder, steps: int) -> None:
    """Moves east along row 14 of map B in a 6 m/s wind from the east, then a landing; poses
    at the camera rate (10 a move) with the wind, battery figures in each step's info."""
    from cpp_mujoco.grid.actions import EAST, LAND

    wind = np.array([-6.0, 0.0, 0.3])
    for step in range(steps + 1):
        for k in range(10):
            t = 3.0 * step + 0.3 * k
            rec.log_pose(t, [step + k / 10, 0.0, 6.0], wind=wind + 0.1 * k)
        landing = step == steps
        col = 3 + min(step + 1, steps) % 12  # back and forth along the row on a long mission
        info = {
            "budget": 30 - step, "coverage_ratio": 0.01 * step, "rejected": False,
            "position": (14, col), "landed": landing,
            "energy_used_j": 480.0 * (step + 1), "state_of_charge": 0.95 - 0.01 * step,
            "battery_voltage_v": 12.4 - 0.01 * step,
        }  # fmt: skip
        action = LAND if landing else EAST
        rec.log_step(3.0 * (step + 1), action, -0.2, info, np.zeros(256, bool), 14 * 16 + col)


def test_recording_holds_the_wind_the_battery_and_each_commanded_waypoint(tmp_path):
    path = tmp_path / "windy.rrd"
    rec = MissionRecorder(path, load_map("B"))
    _log_windy_mission(rec, 3)
    rec.close()
    entities = rrd_entities(path)
    assert "Arrows3D" in entities["/world/wind"]  # the arrow at the UAV
    assert {"Scalars", "SeriesLines"} <= entities["/metrics/wind"]
    assert "Points3D" in entities["/world/waypoint"]
    for metric in ("energy_j", "state_of_charge", "battery_voltage_v"):
        assert "Scalars" in entities[f"/metrics/{metric}"]
    text = rrd_print(path)
    assert "[east, north, speed]" in text
    assert "[-6.0, 0.0, 6.00749" in text  # east, north, speed of the first sample
    # each waypoint from the moment its action began, over the cell it commanded (14, 4) …;
    # the landing's on the ground
    rows = re.findall(r"┆ (P\S+)\s+┆ (\d+)\s+┆ \[\d+\]\s+┆ \[([^\]]+)\]\s+┆ \[\[([^\]]+)\]\]", text)
    assert rows[0] == ("P0D", "0", "1: east → (14, 4)", "-14.0, -26.0, 6.0")
    assert rows[1][:3] == ("PT3S", "1", "2: east → (14, 5)")
    assert rows[-1] == ("PT9S", "3", "4: land → (14, 6)", "-6.0, -26.0, 0.1")
    for view in ("wind at the UAV (m/s)", "state of charge (0-1)", "battery voltage (V)",
                 "battery energy used (J)"):  # fmt: skip
        assert view in text  # the blueprint shows them


def test_a_long_mission_needs_no_rrd_optimize(tmp_path):
    # before: one chunk per entity per flush, so a mission's chunk count grew with its wall
    # time; a demo mission (two videos rendered alongside) got `rerun rrd stats`' warning.
    # Here a flush after every one of 60 moves stands in for a long wall time.
    path = tmp_path / "long_windy.rrd"
    rec = MissionRecorder(path, load_map("B"), properties={"backend": "mujoco"}, wind=True,
                          flush_seconds=1e-6)  # fmt: skip
    _log_windy_mission(rec, 60)
    recording_id = rec.recording_id
    rec.close()
    stats = subprocess.run([RERUN, "rrd", "stats", str(path)], capture_output=True, text=True)
    assert stats.returncode == 0, stats.stderr
    assert "rrd optimize" not in stats.stdout + stats.stderr
    assert "excess:                   0 chunks" in stats.stdout
    assert rrd_num_chunks(path) <= 60
    assert {rid for _, rid in rrd_stores(path)} >= {recording_id}  # the same recording
    entities = rrd_entities(path)  # verified, and everything still in it
    assert {"/world/wind", "/world/waypoint", "/metrics/wind", "/coverage"} <= set(entities)
