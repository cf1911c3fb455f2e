"""Ray as the physics protocol's engine: the same numbers as the local pool, a policy's error ends
the run naming the episode, a dead worker's task is retried, and the command line's ``--ray``.

One local Ray runtime of 2 CPUs for the module (starting one takes seconds); the engine finds it
initialised and uses it, so every run here also checks that it leaves a runtime it did not start.
"""

import json
import os
import re
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cpp_mujoco.cli.main import main
from cpp_mujoco.maps import GridMap
from cpp_mujoco.planners import SafeGreedyPlanner
from cpp_mujoco.protocol.evaluate import evaluate
from tests.test_policy_protocol import FailsInEpisode, run_isolated

SMALL = GridMap.from_ascii(["L.TT", "..T.", "T..L"], name="small")
BUDGETS = [6, 10, 14]  # 2 landing cells × 3 budgets: 6 episodes, 3 tasks
GUSTS = {"wind_speed": 3.0, "gust_std": 1.0}  # seeded per episode: engines must agree on seeds
PER_EPISODE = ("landed", "coverage", "steps", "returns", "trajectories")


@pytest.fixture(scope="module")
def ray_runtime():
    """Skips a test that needs Ray where the optional extra is not installed."""
    ray = pytest.importorskip("ray", reason="Ray is not installed (pip install -e .[ray])")
    ray.init(address="local", num_cpus=2, include_dashboard=False)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def local_result():
    """The local engine's numbers (in this process) to compare Ray's with."""
    return evaluate(SafeGreedyPlanner(), SMALL, **_run(workers=1))


def _run(**extra) -> dict:
    return dict(backend="mujoco", budgets=BUDGETS, env_kwargs=GUSTS, **extra)


def assert_same(a, b) -> None:
    for key in PER_EPISODE:
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)
    assert a.physics.keys() == b.physics.keys()
    for key in a.physics:
        np.testing.assert_array_equal(a.physics[key], b.physics[key], err_msg=key)


class DiesOnce(SafeGreedyPlanner):
    """Kills its worker process at its first action anywhere (leaving ``marker`` behind, so only
    once): what an out-of-memory kill or a crash in native code looks like to Ray."""

    def __init__(self, marker: str):
        super().__init__()
        self.marker = marker

    def act(self, obs):
        if not os.path.exists(self.marker):
            Path(self.marker).touch()
            os._exit(1)
        return super().act(obs)


def test_ray_flies_the_same_episodes_as_the_local_engine(ray_runtime, local_result):
    result = evaluate(SafeGreedyPlanner(), SMALL, **_run(workers=2, engine="ray"))
    assert_same(local_result, result)
    assert result.conditions == local_result.conditions  # the engine decides no number
    assert result.landed.size == 6 and result.physics["energy_used_j"].min() > 0
    assert ray_runtime.is_initialized()  # a runtime it did not start is left running


def test_an_error_in_a_task_ends_the_run_naming_the_episode(ray_runtime):
    started = time.perf_counter()
    # the six episodes fly as one batch, ordered by budget, started with its first one's seed
    with pytest.raises(RuntimeError, match="policy failed in episode 0") as info:
        evaluate(FailsInEpisode(0), SMALL, **_run(engine="ray"))
    notes = info.value.__notes__
    batch = "in a batch of physics episodes: 0 (start (0, 0), budget 6), 3 (start (2, 3), budget 6)"
    assert any(note.startswith(batch) for note in notes), notes
    assert "in a Ray task flying episodes 0, 3, 1, 4, 2, 5" in notes
    assert time.perf_counter() - started < 30  # not retried


def test_a_task_whose_worker_died_is_retried(ray_runtime, local_result, tmp_path):
    marker = tmp_path / "died"
    result = evaluate(DiesOnce(str(marker)), SMALL, **_run(engine="ray"))
    assert marker.exists()  # a worker did die
    assert_same(local_result, result)  # and every episode came back, the same


_OWN_RUNTIME = """
import json, ray
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.planners import SafeGreedyPlanner
from tests.test_ray_engine import SMALL

result = evaluate(SafeGreedyPlanner(), SMALL, backend="mujoco", budgets=[6], workers=1,
                  engine="ray")
print(json.dumps([int(result.landed.sum()), ray.is_initialized()]))
"""


def test_a_runtime_it_starts_itself_is_shut_down_after_the_run():
    """No runtime in the process: a local one of ``workers`` CPUs, for this run only."""
    pytest.importorskip("ray", reason="Ray is not installed (pip install -e .[ray])")
    landed, still_up = json.loads(run_isolated(_OWN_RUNTIME))
    assert landed == 2 and still_up is False


def test_the_command_line_flies_on_ray_with_a_budget_step(ray_runtime, tmp_path, capsys):
    path = tmp_path / "small.png"
    SMALL.save(path)
    out = tmp_path / "out"
    argv = ["evaluate", "--map", str(path), "--planner", "safe-greedy", "--backend", "mujoco",
            "--ray", "--budget-step", "25", "--out", str(out), "--no-progress"]  # fmt: skip
    assert main(argv) == 0, capsys.readouterr().err
    printed = capsys.readouterr().out
    assert "landing" in printed and "small" in printed and "safe-greedy" in printed  # the table
    data = json.loads((out / "mujoco_small_safe-greedy.json").read_text())
    # the 3x4 map's size class is 6..19: every 25th budget and the largest
    assert data["conditions"]["budgets"] == {"min": 6, "max": 19, "step": 13}
    assert data["episodes"] == 2 * 2 and ray_runtime.is_initialized()


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--ray"], ["--ray needs --backend mujoco"]),
        (["--backend", "mujoco", "--ray-address", "10.0.0.1:6379"], ["--ray-address needs --ray"]),
        (["--budget-step", "0"], ["--budget-step", ">= 1"]),
    ],
)
def test_bad_ray_options_are_one_line_and_exit_2(extra, words, tmp_path, capsys):
    argv = ["evaluate", "--map", "C", "--planner", "safe-greedy", "--out", str(tmp_path), *extra]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    assert code == 2
    out, err = capsys.readouterr()
    assert out == "" and "Traceback" not in err
    assert all(w in err for w in words), err


def test_the_grid_has_no_ray_engine():
    with pytest.raises(ValueError, match="engine='ray' needs backend='mujoco'"):
        evaluate(SafeGreedyPlanner(), SMALL, budgets=[6], engine="ray")
    with pytest.raises(ValueError, match="unknown engine 'dask'"):
        evaluate(SafeGreedyPlanner(), SMALL, backend="mujoco", budgets=[6], engine="dask")


def test_without_ray_the_engine_says_how_to_install_it(monkeypatch, tmp_path, capsys):
    from cpp_mujoco.protocol.ray_engine import RayMissingError, import_ray

    monkeypatch.setitem(sys.modules, "ray", None)  # as if the extra were not installed
    with pytest.raises(RayMissingError, match=re.escape("pip install -e .[ray]")):
        import_ray()
    argv = ["evaluate", "--map", "C", "--planner", "safe-greedy", "--backend", "mujoco", "--ray",
            "--out", str(tmp_path)]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "needs Ray" in err and "pip install -e .[ray]" in err and "Traceback" not in err
