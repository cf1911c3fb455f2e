"""The policy protocol: every loop starts its episodes explicitly, so stateful policies (beam
search's plans, a random stream) give the same results however often they are reused; worker
failures end a physics run with their own error; the grid protocol runs in bounded chunks."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.missions.mission import fly_mission
from cpp_mujoco.planners import BeamSearchPlanner, RandomPlanner, SafeGreedyPlanner
from cpp_mujoco.planners.rollout import rollout
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.protocol.policy import start_episodes

ROOT = Path(__file__).resolve().parents[1]
PER_EPISODE = ("landed", "coverage", "steps", "returns", "trajectories")


def assert_same_episodes(a, b) -> None:
    for key in PER_EPISODE:
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)


def map_c_with_landing_cells(k: int) -> GridMap:
    """Map C with only its first ``k`` landing cells: a protocol of k episodes per budget."""
    c = load_map("C")
    landing = np.zeros_like(c.landing)
    landing[tuple(np.argwhere(c.landing)[:k].T)] = True
    return GridMap(landing=landing, target=c.target, nfz=c.nfz, name=f"C{k}")


# ----------------------------------------------------------------------------- episode starts
def test_one_beam_search_planner_through_two_grid_protocols():
    planner = BeamSearchPlanner()
    first, second = evaluate(planner, "C"), evaluate(planner, "C")
    assert_same_episodes(first, second)
    assert second.coverage_ratio == pytest.approx(0.8735, abs=1e-4)
    assert second.landing_ratio == 1.0


def test_one_beam_search_planner_through_physics_protocols_in_and_out_of_process():
    small = map_c_with_landing_cells(2)
    planner = BeamSearchPlanner()
    grid = evaluate(planner, small, budgets=[30])
    run = dict(backend="mujoco", budgets=[30], env_kwargs={"wind_speed": 0.0})
    one = evaluate(planner, small, workers=1, **run)  # one env: episodes one after the other
    again = evaluate(planner, small, workers=1, **run)
    pooled = evaluate(planner, small, workers=2, **run)  # a used planner, pickled to workers
    assert_same_episodes(one, again)
    assert_same_episodes(one, pooled)
    assert one.landing_ratio == 1.0
    np.testing.assert_allclose(one.coverage, grid.coverage, atol=0.05)
    assert one.conditions["env_kwargs"] == {"wind_speed": 0.0}
    assert one.conditions["physics_config"]["wind_speed"] == 0.0


def test_random_planner_reseeds_at_every_protocol():
    planner = RandomPlanner(seed=3)
    assert_same_episodes(evaluate(planner, "B"), evaluate(planner, "B"))
    tiny = GridMap.from_ascii(["LT.", "..L"], name="tiny")
    run = dict(backend="mujoco", budgets=[4], workers=1)
    assert_same_episodes(evaluate(planner, tiny, **run), evaluate(planner, tiny, **run))


def test_rollout_and_mission_start_a_stateful_planner_afresh():
    c = load_map("C")
    planner = BeamSearchPlanner()
    pos = np.flatnonzero(c.landing)
    budget = np.full(pos.size, 40)
    coverage = np.zeros((pos.size, c.landing.size), dtype=bool)
    first = rollout(c, planner, pos, budget, coverage)
    second = rollout(c, planner, pos, budget, coverage)
    for a, b in zip(first, second, strict=True):
        np.testing.assert_array_equal(a, b)
    missions = [fly_mission(planner, "C", budget=40, backend="grid") for _ in range(2)]
    assert missions[0].actions == missions[1].actions and missions[1].landed
    assert missions[1].coverage_ratio > 0.5


def test_start_episodes_calls_reset_only_where_there_is_one():
    calls = []

    class Stateful:
        def reset(self, num_episodes, seed=None):
            calls.append((num_episodes, seed))

    start_episodes(Stateful(), 7, seed=2)
    start_episodes(SafeGreedyPlanner(), 7)  # no reset: nothing happens, nothing breaks
    assert calls == [(7, 2)]
    obs = evaluate(SafeGreedyPlanner(), "C", budgets=[30])
    assert obs.landing_ratio == 1.0
    # a plain function works as a policy as well
    fn = evaluate(lambda o: SafeGreedyPlanner().act(o), "C", budgets=[30])
    assert_same_episodes(obs, fn)


# ----------------------------------------------------------------------------- chunks, progress
def test_chunked_grid_protocol_equals_one_batch():
    from cpp_mujoco.agent import load_agent
    from cpp_mujoco.protocol.physics_tasks import one_torch_thread

    budgets = range(25, 76, 10)  # 72 episodes: chunks of 7, the last one of 2
    cells = load_map("C").landing.size
    for policy in (BeamSearchPlanner(), load_agent("C")):
        with one_torch_thread():  # small batches: a thread pool on a shared box costs more
            whole = evaluate(policy, "C", budgets=budgets)
            chunked = evaluate(policy, "C", budgets=budgets, chunk_cells=7 * cells + 5)
        assert_same_episodes(whole, chunked)
        assert chunked.conditions["chunk_episodes"] == 7
        assert whole.conditions["chunk_episodes"] == whole.landed.size == 72
    with pytest.raises(ValueError, match="on_step needs the protocol in one batch"):
        evaluate(SafeGreedyPlanner(), "C", chunk_cells=cells, on_step=lambda *a: None)


def test_chunks_bound_the_batch_the_policy_sees():
    sizes = []

    class Recording(SafeGreedyPlanner):
        def act(self, obs):
            sizes.append(obs["coverage"].shape[0])
            return super().act(obs)

    cells = load_map("B").landing.size
    result = evaluate(Recording(), "B", budgets=[30, 40, 50], chunk_cells=4 * cells + 3)
    assert max(sizes) == 4 and result.landed.size == 24


def test_grid_progress_bar_is_quiet_by_default(capsys):
    evaluate(SafeGreedyPlanner(), "C", budgets=[30])
    assert capsys.readouterr().err == ""
    evaluate(SafeGreedyPlanner(), "C", budgets=[30], progress=True)
    err = capsys.readouterr().err
    assert "grid C" in err and "12/12" in err


# ----------------------------------------------------------------------------- map and conditions
def test_result_carries_the_map_it_evaluated_and_its_conditions(tmp_path):
    mine = GridMap.from_ascii(["LTT", "T.T", "TTL"], name="A")
    path = tmp_path / "A.png"
    mine.save(path)
    result = evaluate(SafeGreedyPlanner(), path, budgets=range(3, 10, 2))
    assert result.grid_map.digest == mine.digest
    assert result.map_name == f"A-{mine.digest[:8]}"  # not the bundled map A
    result.to_json(tmp_path / "r.json")
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["map"] == result.map_name and data["map_digest"] == mine.digest
    assert data["map_source"] == str(path.resolve()) and data["map_bundled"] is False
    conditions = data["conditions"]
    assert conditions["backend"] == "grid" and conditions["episodes"] == 8
    assert conditions["budgets"] == {"min": 3, "max": 9, "step": 2}
    assert conditions["fov_side"] == 3 and conditions["env_kwargs"] == {}
    assert conditions["package_version"]
    odd = evaluate(
        SafeGreedyPlanner(fov_side=1), mine, budgets=[3, 4, 9], env_kwargs={"fov_side": 1}
    )
    assert odd.conditions["budgets"] == {"min": 3, "max": 9, "step": None, "values": [3, 4, 9]}
    assert odd.conditions["fov_side"] == 1 and odd.upper_bound != result.upper_bound


def test_options_the_grid_does_not_know_are_errors_not_ignored():
    with pytest.raises(ValueError, match=r"wind_speed.*backend='mujoco'"):
        evaluate(SafeGreedyPlanner(), "C", budgets=[30], env_kwargs={"wind_speed": 6.0})
    with pytest.raises(ValueError, match="fov_side"):
        evaluate(SafeGreedyPlanner(), "C", budgets=[30], env_kwargs={"fov_side": 0})


# ----------------------------------------------------------------------------- worker failures
class FailsInEpisode(SafeGreedyPlanner):
    """Flies like the safe greedy planner until the episode seeded ``bad`` starts."""

    def __init__(self, bad: int):
        super().__init__()
        self.bad, self.episode = bad, None

    def reset(self, num_episodes, seed=None):
        self.episode = seed

    def act(self, obs):
        if self.episode == self.bad:
            raise RuntimeError(f"policy failed in episode {self.bad}")
        return super().act(obs)


class UnpicklesBadly(SafeGreedyPlanner):
    """Pickles fine here; cannot be restored in a worker (what an initializer used to choke on)."""

    def __setstate__(self, state):
        raise RuntimeError("cannot restore this policy in a worker")


_FAILURES = """
import json, time
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.planners import SafeGreedyPlanner
from tests.test_policy_protocol import FailsInEpisode, UnpicklesBadly, map_c_with_landing_cells

small = map_c_with_landing_cells(3)
cases = {
    "bad option": (SafeGreedyPlanner(), {"env_kwargs": {"wind_sped": 3.0}}),
    "episode 0": (FailsInEpisode(0), {}),  # one batch, started with its first episode's seed
    "unpickle": (UnpicklesBadly(), {}),
}
out = {}
for name, (policy, extra) in cases.items():
    t = time.perf_counter()
    try:
        evaluate(policy, small, backend="mujoco", budgets=[4, 6], workers=2, **extra)
        out[name] = ["no error", "", 0.0]
    except Exception as exc:
        out[name] = [type(exc).__name__, str(exc), time.perf_counter() - t]
print(json.dumps(out))
"""


def run_isolated(code: str, timeout: float = 120, script=None) -> str:
    """Run ``code`` in a fresh interpreter (as the file ``script`` if given); a hang fails the
    test (its workers are killed too)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if script is not None:
        script.write_text(code)
    command = [sys.executable, str(script)] if script is not None else [sys.executable, "-c", code]
    proc = subprocess.Popen(
        command, cwd=ROOT, env=env, text=True, start_new_session=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        pytest.fail(f"hung: no result after {timeout} s")
    assert proc.returncode == 0, stderr[-2000:]
    return stdout.strip().splitlines()[-1]


_NO_MAIN_GUARD = """
import json
from cpp_mujoco.agent import load_agent
from cpp_mujoco.protocol.evaluate import evaluate

try:  # at import, without `if __name__ == "__main__":` — every spawned worker re-runs this
    evaluate(load_agent("A"), "A", backend="mujoco", budgets=[25], workers=2, progress=False)
    print(json.dumps(["no error", []]))
except Exception as exc:
    if __name__ == "__mp_main__":
        raise  # a spawned worker re-running this file: fail as such a script does
    print(json.dumps([type(exc).__name__, getattr(exc, "__notes__", [])]))
"""


def test_a_script_without_a_main_guard_gets_an_error_not_a_hang(tmp_path):
    """The policy (a 4.8 MB network here) no longer rides in spawn's pipe handshake, where a
    worker that died re-running the script left the parent blocked forever."""
    kind, notes = json.loads(run_isolated(_NO_MAIN_GUARD, script=tmp_path / "no_guard.py"))
    assert kind == "BrokenProcessPool"
    assert any('if __name__ == "__main__":' in note for note in notes)


def test_worker_failures_end_the_run_with_the_workers_error():
    out = json.loads(run_isolated(_FAILURES))
    kind, message, seconds = out["bad option"]
    assert "wind_sped" in message and seconds < 10  # rejected in the parent, no worker started
    assert out["episode 0"][:2] == ["RuntimeError", "policy failed in episode 0"]
    assert out["unpickle"][:2] == ["RuntimeError", "cannot restore this policy in a worker"]


def test_physics_chunks_hold_every_episode_once_longest_first():
    from cpp_mujoco.protocol.physics_tasks import chunk_count, chunks

    tasks = [(i, (0, i % 36), 25 + i // 36) for i in range(1836)]  # map A's protocol shape
    count = chunk_count(len(tasks))
    assert count == 10 and chunk_count(396) == 4 and chunk_count(40) == 1  # not the workers
    parts = chunks(tasks, count)
    assert len(parts) == count and {len(p) for p in parts} == {183, 184}
    assert sorted(t for part in parts for t in part) == tasks
    budgets = [[t[2] for t in part] for part in parts]
    assert all(b == sorted(b) for b in budgets)  # each chunk a run of similar budgets …
    assert budgets[0][-1] == 75 and budgets[-1][0] == 25  # … the longest chunk first
