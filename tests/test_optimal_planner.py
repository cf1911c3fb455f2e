"""The exact planner: its model against every action sequence on small maps, its missions flown
through the MDP, its guarantees against beam search, and its cache."""

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from cpp_mujoco.cli.main import main
from cpp_mujoco.grid.graph import build_graph
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.grid.wind import GridWind
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.planners import make_planner
from cpp_mujoco.planners.optimal import beam_missions, solve_episodes
from cpp_mujoco.planners.optimal_model import EpisodeModel
from cpp_mujoco.planners.optimal_solver import SolverOptions, solve_episode
from cpp_mujoco.protocol.evaluate import evaluate, protocol_episodes
from cpp_mujoco.protocol.optimum import default_folder
from cpp_mujoco.protocol.optimum_cache import CacheError, OptimumCache

# 0 open, L landing, T target, N no-fly, Y target + no-fly (seen only from beside)
SMALL = [
    "L L 0 T T",
    "L N N Y T",
    "0 0 T N 0",
    "T N 0 0 T",
    "T T 0 Y L",
]


def small_map(rows=SMALL, name="small") -> GridMap:
    cells = np.array([r.split() for r in rows])
    return GridMap(
        landing=cells == "L",
        target=np.isin(cells, ["T", "Y"]),
        nfz=np.isin(cells, ["N", "Y"]),
        name=name,
    )


def best_by_every_sequence(grid_map: GridMap, start, budget: int) -> int:
    """Target cells seen by the best landed episode over all 5^budget action sequences."""
    sequences = np.array(list(itertools.product(range(5), repeat=budget)), dtype=np.int64)
    mdp = GridMDP(grid_map, len(sequences))
    mdp.reset(np.random.default_rng(0), start=start, budget=budget)
    for t in range(budget):
        mdp.step(sequences[:, t])
    return int(mdp.seen_targets[mdp.landed].max())


@pytest.mark.parametrize(
    "solver, memory, relaxation_start",
    [("highs", 1, True), ("cp-sat", 1, True), ("highs", 2, True), ("highs", 2, False)],
)
@pytest.mark.parametrize("budget", [1, 2, 3, 5, 7])
def test_the_model_finds_what_every_action_sequence_finds(budget, solver, memory, relaxation_start):
    grid_map = small_map()
    g = build_graph(grid_map)
    options = SolverOptions(solver=solver, memory=memory, relaxation_start=relaxation_start)
    for row, col in np.argwhere(grid_map.landing):
        mission = solve_episode(g, int(row * 5 + col), budget, options=options)
        assert mission.status == "optimal"
        assert mission.seen == mission.bound == best_by_every_sequence(grid_map, (row, col), budget)
        seen, landed = g.fly(int(row * 5 + col), mission.actions, np.zeros(25, bool))
        assert landed and seen == mission.seen and mission.actions.size <= budget


def test_the_start_view_needs_a_hover_a_return_or_a_landing():
    # a start against the north edge with targets round it: a hover (the rejected move north),
    # a return or landing at once shows them; in the open, only a return or landing at once
    for rows, start in ((["T L T 0 L", "T T T 0 0"], (0, 1)),
                        (["T L 0 0 0 L", "T 0 0 0 T T"], (0, 1)),  # 6: only a hover sees 4
                        (["T T T 0 0", "T L T 0 L", "T T T 0 0"], (1, 1))):  # fmt: skip
        grid_map = small_map(rows, "ring")
        g = build_graph(grid_map)
        cell = start[0] * grid_map.shape[1] + start[1]
        for budget in (1, 2, 3, 4, 5, 6):
            mission = solve_episode(g, cell, budget)
            assert mission.seen == best_by_every_sequence(grid_map, start, budget)


def test_the_committed_missions_fly_and_beat_beam_search():
    # map C's whole protocol, from the committed cache: read and flown, nothing solved
    grid_map = load_map("C")
    folder = default_folder()
    cache = OptimumCache(folder, grid_map)
    planner = make_planner("optimal", optimal={"cache_folder": folder})
    result = evaluate(planner, grid_map)
    beam = evaluate(make_planner("beam-search"), grid_map)
    assert result.landing_ratio == 1.0
    assert planner.statuses == {"optimal": result.landed.size}
    targets = grid_map.target.sum()
    for i, (start, budget) in enumerate(zip(result.starts, result.budgets, strict=True)):
        entry = cache.get(tuple(start), int(budget))
        assert entry["status"] == "optimal" and entry["seen"] == entry["bound"]
        assert result.coverage[i] * targets == pytest.approx(entry["seen"])  # the env's own count
    assert (result.coverage >= beam.coverage - 1e-12).all()
    assert result.conditions["policy"]["solver"].startswith("HiGHS")


def test_an_episode_without_a_way_home_is_infeasible_not_a_crash():
    grid_map = small_map()
    g = build_graph(grid_map)
    far = 4 * 5 + 0  # bottom-left, several moves from the nearest landing cell
    mission = solve_episode(g, far, 2)
    assert mission.status == "infeasible" and mission.actions.size == 0
    with pytest.raises(ValueError, match="time limit"):
        SolverOptions(time_limit_s=float("nan"))
    with pytest.raises(ValueError, match="memory"):
        SolverOptions(memory=3)


def test_a_mid_episode_replan_counts_what_was_seen():
    grid_map = small_map()
    g = build_graph(grid_map)
    seen = np.zeros(25, bool)
    seen[[3, 4, 8, 9]] = True  # the top-right targets, already seen
    mission = solve_episode(g, 1, 7, seen)
    assert mission.status == "optimal"
    assert g.fly(1, mission.actions, seen) == (mission.seen, True)


def test_the_cache_is_reused_and_resumed(tmp_path):
    grid_map = load_map("C")
    starts, budgets = protocol_episodes(grid_map, [75])
    cache = OptimumCache(tmp_path, grid_map)
    first = solve_episodes(grid_map, starts[:5], budgets[:5], SolverOptions(5), cache)
    saved = json.loads(cache.path.read_text())
    assert len(saved["entries"]) == 5 and saved["map_digest"] == grid_map.digest
    # a second run solves only what is new, and keeps the known entries as they were
    again = OptimumCache(tmp_path, grid_map)
    both = solve_episodes(grid_map, starts, budgets, SolverOptions(5), again)
    assert both[:5] == first
    assert len(json.loads(cache.path.read_text())["entries"]) == len(starts)


def test_entries_name_the_models_memory_and_the_solver_still_reads_them(tmp_path):
    grid_map = small_map()
    starts = np.argwhere(grid_map.landing)[:2]
    budgets = np.array([7, 9])
    cache = OptimumCache(tmp_path, grid_map)
    entries = solve_episodes(grid_map, starts, budgets, SolverOptions(5, memory=2), cache)
    assert {e["solver"] for e in entries} == {"HiGHS " + _highs_release() + ", 2 cells of memory"}
    assert all(e["status"] == "optimal" for e in entries)
    # an unproven entry of the remembered model is HiGHS's: not solved again under the same
    # limit by HiGHS, solved again by a longer limit or by the other solver
    start = tuple(starts[0])
    cache.entries[f"{start[0]},{start[1]},7"]["status"] = "feasible"
    assert cache.usable(start, 7, "HiGHS 9.9.9", 5)
    assert not cache.usable(start, 7, "HiGHS 9.9.9", 10)
    assert not cache.usable(start, 7, "OR-Tools CP-SAT 9.9", 5)


def _highs_release() -> str:
    from cpp_mujoco.planners.optimal_solver import solver_version

    return solver_version("highs").split()[1]


def test_a_foreign_or_broken_cache_is_refused_and_kept(tmp_path):
    grid_map = load_map("C")
    path = tmp_path / f"{grid_map.digest}.json"
    for text, why in (
        ("{not json", "cannot be read"),
        (json.dumps({"format": "other"}), "not a cpp_mujoco.optimum/1 file"),
        (json.dumps({"format": "cpp_mujoco.optimum/1", "map_digest": "0" * 12}), "belongs to"),
    ):
        path.write_text(text)
        with pytest.raises(CacheError, match=why):
            OptimumCache(tmp_path, grid_map)
        assert main(["optimum", "--map", "C", "--first", "1", "--optimum", str(tmp_path)]) == 2
        assert path.read_text() == text


def test_results_carry_the_optimum_beside_the_policy():
    result = evaluate(make_planner("safe-greedy"), "C", budgets=[25, 26, 75])
    summary = result.summary()["optimum"]
    assert summary["episodes_known"] == result.landed.size
    assert summary["statuses"] == {"optimal": result.landed.size}
    assert summary["gap_to_optimal"] >= 0
    assert all(row["optimum"] >= row["coverage_ratio"] for row in result.per_budget)
    assert np.all(result.optimum["coverage"] >= result.coverage - 1e-12)
    # a result in the grid's wind option carries none: its moves cost what the wind makes them
    windy = GridConfig(wind=GridWind())
    assert evaluate(make_planner("safe-greedy"), "C", budgets=[25], config=windy).optimum == {}


def test_beam_missions_land_within_their_budget():
    grid_map = load_map("B")
    g = build_graph(grid_map)
    cells = np.flatnonzero(grid_map.landing.reshape(-1))[:3]
    for cell, actions in zip(cells, beam_missions(grid_map, cells, np.full(3, 30)), strict=True):
        _, landed = g.fly(int(cell), actions, np.zeros(g.num_cells, bool))
        assert landed and actions.size <= 30


def test_the_docs_table_is_the_result_files():
    import runpy

    from cpp_mujoco.map_sets.sets import load_map_set

    script = runpy.run_path(str(Path(__file__).parent.parent / "scripts" / "optimum_report.py"))
    assert script["main"](["--check"]) == 0
    data = json.loads(script["RESULT"].read_text())
    for row in data["results"]:  # each committed result names its map, policy and optimum
        assert row["map_digest"] == load_map(row["map"]).digest
        assert row["optimum"]["episodes_known"] == row["episodes"]
    sample = runpy.run_path(str(Path(__file__).parent.parent / "scripts" / "optimum_sample.py"))
    samples = sorted(Path(sample["ROOT"], "results").glob("optimum_*-v*.json"))
    assert len(samples) >= 4  # heldout16, heldout32, city32 and the families' sets
    for name in (p.stem.removeprefix("optimum_") for p in samples):
        assert sample["main"](["--map-set", name, "--check"]) == 0
        drawn = json.loads(sample["result_path"](name).read_text())
        maps = {m.digest: m for m in load_map_set(name)}
        for episode in drawn["episodes"]:  # every sampled episode is in the committed cache
            cache = OptimumCache(default_folder(), maps[episode["map_digest"]])
            assert cache.get(tuple(episode["start"]), episode["budget"]) is not None


def test_a_failing_worker_stops_the_run_and_keeps_what_was_solved(tmp_path, monkeypatch):
    import cpp_mujoco.planners.optimal as optimal

    real = optimal.solve_episode

    def fails_at_the_last_budget(g, cell, budget, **kwargs):
        if budget == 75:
            raise RuntimeError("solver worker broke")
        return real(g, cell, budget, **kwargs)

    monkeypatch.setattr(optimal, "solve_episode", fails_at_the_last_budget)  # forked workers too
    grid_map = load_map("C")
    starts, budgets = protocol_episodes(grid_map, [74, 75])
    order = np.argsort(budgets, kind="stable")  # every 74 before the first 75
    cache = OptimumCache(tmp_path, grid_map)
    with pytest.raises(RuntimeError, match="solver worker broke"):
        solve_episodes(grid_map, starts[order], budgets[order], SolverOptions(5), cache, jobs=2)
    kept = json.loads(cache.path.read_text())["entries"]
    assert kept and all(key.endswith(",74") for key in kept)


def test_a_results_trajectory_flies_again_as_actions():
    from cpp_mujoco.planners.optimal import trajectory_actions

    grid_map = load_map("B")
    g = build_graph(grid_map)
    result = evaluate(make_planner("safe-greedy"), grid_map, budgets=[30, 60])
    for i in range(result.landed.size):
        actions = trajectory_actions(g, result.trajectories[i])
        cell = int(result.starts[i, 0] * 16 + result.starts[i, 1])
        seen, landed = g.fly(cell, actions, np.zeros(g.num_cells, bool))
        assert landed and seen == round(result.coverage[i] * grid_map.target.sum())
        assert actions.size == result.steps[i]


def test_two_writers_of_one_cache_keep_each_others_entries(tmp_path):
    grid_map = load_map("C")
    starts, budgets = protocol_episodes(grid_map, [75])
    one, two = OptimumCache(tmp_path, grid_map), OptimumCache(tmp_path, grid_map)
    solve_episodes(grid_map, starts[:2], budgets[:2], SolverOptions(5), one)
    solve_episodes(grid_map, starts[2:4], budgets[2:4], SolverOptions(5), two)
    assert len(OptimumCache(tmp_path, grid_map).entries) == 4


def test_the_command_line_flies_the_optimal_planner_beside_the_others(tmp_path, capsys):
    args = ["evaluate", "--map", "C", "--planner", "optimal", "beam-search", "--budget-step",
            "25", "--optimum", str(default_folder()), "--out", str(tmp_path)]  # fmt: skip
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "gap to optimal" in out and "optimal" in out
    saved = json.loads((tmp_path / "grid_C_optimal.json").read_text())
    assert saved["optimum"]["gap_to_optimal"] == 0.0
    assert saved["conditions"]["policy"]["statuses"] == {"optimal": saved["episodes"]}
    with pytest.raises(SystemExit) as bad:
        main(["optimum", "--map", "C", "--time-limit", "nan"])
    assert bad.value.code == 2


@pytest.mark.parametrize("memory", [1, 2])
def test_a_known_mission_is_a_point_of_the_model(memory):
    # the warm start must satisfy every row, or the solver drops it
    grid_map = small_map()
    g = build_graph(grid_map)
    cells = np.flatnonzero(grid_map.landing.reshape(-1))
    budgets = np.full(cells.size, 9)
    for cell, actions in zip(cells, beam_missions(grid_map, cells, budgets), strict=True):
        model = EpisodeModel(g, int(cell), 8, np.zeros(g.num_cells, bool), memory=memory)
        x = model.hint(actions)
        assert x is not None
        ax = model.A @ x
        assert ((ax >= model.lo - 1e-9) & (ax <= model.hi + 1e-9)).all()
        assert (x <= model.upper).all() and model.objective @ x == g.fly(
            int(cell), actions, np.zeros(25, bool)
        )[0]


def test_the_relaxations_paths_are_missions_and_the_start_changes_no_answer():
    from cpp_mujoco.planners.optimal_relaxation import peeled_paths
    from cpp_mujoco.planners.optimal_solver import _relaxation

    grid_map = load_map("C")
    g = build_graph(grid_map)
    width = grid_map.shape[1]
    for (row, col), budget in (((14, 13), 37), ((15, 2), 45)):
        start = row * width + col
        model = EpisodeModel(g, start, budget - 1, np.zeros(g.num_cells, bool))
        x, value = _relaxation(model, 60.0)
        paths = peeled_paths(model, x)
        assert paths and np.isfinite(value)
        for walk in paths:  # each path a mission: it lands within the budget, under the bound
            actions = model.actions(walk)
            seen, landed = g.fly(start, actions, np.zeros(g.num_cells, bool))
            assert landed and actions.size <= budget and seen <= value + 1e-6
        plain = solve_episode(g, start, budget, options=SolverOptions(relaxation_start=False))
        read = solve_episode(g, start, budget)
        assert plain.status == read.status == "optimal" and plain.seen == read.seen


@pytest.mark.parametrize("budget", [2, 3, 5, 7])
def test_the_model_with_two_cells_of_memory_finds_what_every_action_sequence_finds(budget):
    from cpp_mujoco.planners.optimal_solver import _highs

    grid_map = small_map()
    g = build_graph(grid_map)
    for row, col in np.argwhere(grid_map.landing):
        start = int(row * 5 + col)
        model = EpisodeModel(g, start, budget - 1, np.zeros(25, bool), memory=2)
        answer = _highs(model, SolverOptions(), None)
        seen, landed = g.fly(start, model.actions(answer.x), np.zeros(25, bool))
        best = best_by_every_sequence(grid_map, (row, col), budget)
        assert answer.status == "optimal" and landed
        assert seen == round(float(model.objective @ answer.x)) == best


def test_the_report_re_flies_only_the_named_policies(tmp_path, monkeypatch):
    import runpy
    from types import SimpleNamespace

    import cpp_mujoco.protocol.evaluate as protocol

    script = runpy.run_path(str(Path(__file__).parent.parent / "scripts" / "optimum_report.py"))
    committed = json.loads(script["RESULT"].read_text())
    result = tmp_path / "optimum_abc.json"
    result.write_text(json.dumps(committed))
    script["evaluate_all"].__globals__["RESULT"] = result
    flown = []

    def fake_evaluate(policy, grid_map, policy_name, **kwargs):
        flown.append((grid_map.name, policy_name))
        row = {"map": grid_map.name, "policy": policy_name, "re-flown": True}
        return SimpleNamespace(optimum=True, summary=lambda: row)

    monkeypatch.setattr(protocol, "evaluate", fake_evaluate)
    data = script["evaluate_all"](2, 10, ["general"])
    assert flown == [("A", "general"), ("B", "general"), ("C", "general")]
    assert data == json.loads(result.read_text())
    assert data["physics"] == committed["physics"]
    for row, before in zip(data["results"], committed["results"], strict=True):
        assert (row["map"], row["policy"]) == (before["map"], before["policy"])
        assert ("re-flown" in row) == (row["policy"] == "general")
        if row["policy"] != "general":
            assert row == before
    for argv in (["--policy", "general"], ["--evaluate", "--policy", "ddqn-D"]):
        with pytest.raises(SystemExit):
            script["main"](argv)
