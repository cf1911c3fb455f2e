"""Flying one mission end to end: the CLI's recording and videos, and interrupted runs."""

import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import pytest

from cpp_mujoco.cli.main import main
from cpp_mujoco.maps import GridMap
from cpp_mujoco.missions.mission import fly_mission
from cpp_mujoco.planners import SafeGreedyPlanner
from tests.test_review import rrd_entities, rrd_print

SMALL = GridMap.from_ascii(["LL.TT", "LL.TT", "....."], name="small")


@pytest.fixture()
def small_map(tmp_path) -> Path:
    path = tmp_path / "small.png"
    SMALL.save(path)
    return path


def test_fly_writes_a_verified_recording_and_decodable_videos(tmp_path, small_map, capsys):
    rrd, video, onboard = tmp_path / "m.rrd", tmp_path / "chase.mp4", tmp_path / "onboard.mp4"
    # budget 4: a move out, one back and the landing, every frame rendered by both cameras
    code = main(["fly", "--map", str(small_map), "--planner", "safe-greedy", "--budget", "4",
                 "--start", "0,1", "--rrd", str(rrd), "--video", str(video),
                 "--onboard-video", str(onboard)])  # fmt: skip
    assert code == 0
    out = capsys.readouterr().out
    assert "landed" in out and f"rerun {rrd}" in out
    entities = rrd_entities(rrd)
    assert "Transform3D" in entities["/world/uav"]
    assert "LineStrips3D" in entities["/world/trajectory"]
    assert "EncodedImage" in entities["/camera/image"]
    assert "Scalars" in entities["/metrics/energy_j"]
    for path in (video, onboard):
        frames = iio.imread(path)
        assert frames.shape[0] > 20 and frames.std() > 5  # real frames, not blank


def test_grid_backend_recording(tmp_path):
    outcome = fly_mission(SafeGreedyPlanner(), SMALL, budget=8, start=(0, 1), backend="grid",
                          rrd=tmp_path / "g.rrd")  # fmt: skip
    assert outcome.landed and outcome.coverage_ratio == 1.0
    assert "LineStrips3D" in rrd_entities(tmp_path / "g.rrd")["/world/footprint"]
    # the recording says what was flown: the map's identity, the policy, the conditions
    properties = rrd_print(tmp_path / "g.rrd")
    assert f"[{SMALL.digest}]" in properties and "[safe-greedy]" in properties
    assert outcome.map == "small" and outcome.policy == "safe-greedy"


class _Interrupting:
    def __init__(self, after: int):
        self.calls, self.after, self.inner = 0, after, SafeGreedyPlanner()

    def act(self, obs):
        self.calls += 1
        if self.calls > self.after:
            raise KeyboardInterrupt
        return self.inner.act(obs)


def test_an_interrupted_mission_leaves_readable_files_that_say_so(tmp_path):
    rrd, onboard = tmp_path / "m.rrd", tmp_path / "onboard.mp4"
    with pytest.raises(KeyboardInterrupt) as info:
        fly_mission(_Interrupting(1), SMALL, budget=8, start=(0, 1), rrd=rrd, onboard_video=onboard)
    partial = tmp_path / "onboard.partial.mp4"
    assert info.value.files_finalised == {"rrd": str(rrd), "onboard_video": str(partial)}
    assert "Transform3D" in rrd_entities(rrd)["/world/uav"]
    assert "interrupted" in rrd_print(rrd)  # the recording's last event says it was cut
    assert not onboard.exists()  # a cut video never passes for a complete one
    assert iio.imread(partial).shape[0] > 5


def test_fly_bad_input_messages(tmp_path, small_map, capsys):
    assert main(["fly", "--map", "A", "--agent", "nonexistent"]) == 2
    err = capsys.readouterr().err
    assert "'nonexistent'" in err and "bundled: A, A-wind, B, B-wind, C, C-wind" in err
    assert main(["fly", "--map", str(small_map), "--planner", "safe-greedy", "--start", "x"]) == 2
    assert "ROW,COL" in capsys.readouterr().err
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code = main(["fly", "--map", str(small_map), "--planner", "safe-greedy", "--budget", "4",
                 "--start", "0,1", "--rrd", str(blocker / "m.rrd")])  # fmt: skip
    assert code == 2 and "cannot write recording" in capsys.readouterr().err


def test_fly_with_an_agent_for_another_map_size(tmp_path, small_map, capsys):
    # the bundled agents are 16x16; the small map is 3x5
    code = main(["fly", "--map", str(small_map), "--agent", "A", "--budget", "5", "--start", "0,1"])
    assert code == 2
    err = capsys.readouterr().err
    assert "trained on 16x16" in err and "Traceback" not in err


def test_no_gl_backend_is_a_clear_message(tmp_path, small_map):
    # a fresh process, so MuJoCo is not imported yet; no backend passes the probe
    script = (
        "import sys; import cpp_mujoco.physics.view.rendering as r;"
        "r.gl_works = lambda backend, timeout=60.0: False;"
        "from cpp_mujoco.cli.main import main;"
        f"sys.exit(main(['fly', '--map', {str(small_map)!r}, '--planner', 'safe-greedy',"
        f" '--start', '0,1', '--video', {str(tmp_path / 'v.mp4')!r}]))"
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert result.returncode == 2
    assert "no offscreen GL backend works" in result.stderr
    assert "Traceback" not in result.stderr
