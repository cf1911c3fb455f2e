"""The exact search (can a mission of b units see n targets?) against every action sequence on
small maps, against the committed proofs of map B, and closing an open episode of a cache."""

import itertools

import numpy as np
import pytest

from cpp_mujoco.grid.graph import build_graph
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.planners import optimal_search
from cpp_mujoco.planners.optimal import close_gaps
from cpp_mujoco.planners.optimal_search import CoverageSearch, SearchOptions
from cpp_mujoco.planners.optimal_solver import SolverOptions, solve_episode
from cpp_mujoco.protocol.optimum import default_folder
from cpp_mujoco.protocol.optimum_cache import OptimumCache
from tests.test_optimal_planner import small_map


def best_of_every_sequence(grid_map: GridMap, start, budget: int, fov_side: int = 3) -> int:
    sequences = np.array(list(itertools.product(range(5), repeat=budget)), dtype=np.int64)
    mdp = GridMDP(grid_map, len(sequences), GridConfig(fov_side=fov_side))
    mdp.reset(np.random.default_rng(0), start=start, budget=budget)
    for t in range(budget):
        mdp.step(sequences[:, t])
    return int(mdp.seen_targets[mdp.landed].max())


def assert_search_finds_the_best(grid_map: GridMap, budgets, fov_side: int = 3) -> None:
    g = build_graph(grid_map, fov_side)
    width = grid_map.shape[1]
    for row, col in np.argwhere(grid_map.landing):
        search = CoverageSearch(g, int(row * width + col), SearchOptions(key_targets=6))
        for budget in budgets:
            best = best_of_every_sequence(grid_map, (row, col), budget, fov_side)
            found = search.ask(budget, best)
            assert found.status == "found" and found.seen >= best
            assert found.actions.size <= budget
            assert g.fly(int(row * width + col), found.actions) == (found.seen, True)
            assert search.ask(budget, best + 1).status == "none"


@pytest.mark.parametrize("budget", [1, 2, 3, 5, 7])
def test_the_search_finds_what_every_action_sequence_finds(budget):
    assert_search_finds_the_best(small_map(), [budget])


def test_the_start_view_needs_a_hover_a_return_or_a_landing():
    for rows in (["T L T 0 L", "T T T 0 0"], ["T L 0 0 0 L", "T 0 0 0 T T"],
                 ["T T T 0 0", "T L T 0 L", "T T T 0 0"]):  # fmt: skip
        assert_search_finds_the_best(small_map(rows, "ring"), range(1, 7))


def test_more_than_64_targets_and_obstacles_with_a_5x5_view():
    rng = np.random.default_rng(3)
    target = rng.random((9, 10)) < 0.85
    landing = np.zeros_like(target)
    landing[4, 0] = landing[8, 9] = True
    obstacle = np.zeros_like(target)
    obstacle[[2, 6, 6], [3, 5, 6]] = True
    target &= ~landing & ~obstacle
    nfz = np.zeros_like(target)
    nfz[6, 6] = True  # a tall building: no-fly and hides what is behind it
    grid_map = GridMap(landing=landing, target=target, nfz=nfz, obstacle=obstacle, name="wide")
    assert target.sum() > 64  # two words of targets seen
    assert_search_finds_the_best(grid_map, [4, 6], fov_side=5)


def test_map_b_needs_54_units_to_see_every_target_from_15_4():
    # the proof that closed map B's last open episodes (via the cache's tighten)
    grid_map = load_map("B")
    search = CoverageSearch(build_graph(grid_map), 15 * 16 + 4)
    every = int(grid_map.target.sum())
    found = search.ask(54, every)
    assert found.status == "found" and found.seen == every
    assert search.ask(53, every).status == "none"
    entry = OptimumCache(default_folder(), grid_map).get((15, 4), 53)
    assert entry["status"] == "optimal" and entry["bound"] == every - 1
    assert entry["solver"] == search.name


def test_close_gaps_proves_an_open_episode_and_leaves_it_open_without_time():
    grid_map = small_map()
    g = build_graph(grid_map)
    mission = solve_episode(g, 0, 7, options=SolverOptions())
    assert mission.status == "optimal"
    loose = type(mission)(mission.actions, mission.seen, mission.seen + 2, "feasible", 0.0)
    cache = OptimumCache.in_memory(grid_map)
    cache.put((0, 0), 7, loose, 1.0, 1, "HiGHS 1.16.0")
    starts, budgets = np.array([[0, 0]]), np.array([7])
    [entry] = close_gaps(grid_map, starts, budgets, SearchOptions(key_targets=6), cache)
    assert entry["status"] == "optimal" and entry["bound"] == entry["seen"] == mission.seen
    assert entry["solver"].startswith("key-target search")
    with pytest.raises(ValueError, match="not in the optimum cache"):  # never solved: say so
        close_gaps(grid_map, np.array([[0, 1]]), np.array([7]), SearchOptions(), cache)


def test_a_question_out_of_time_is_unknown(monkeypatch):
    monkeypatch.setattr(optimal_search, "_SLICE", 1)
    grid_map = small_map()
    g = build_graph(grid_map)
    search = CoverageSearch(g, 0, SearchOptions(time_limit_s=1e-9, key_targets=6))
    assert search.ask(7, 10).status == "unknown"
    with pytest.raises(ValueError, match="budgets of at most 254"):
        search.ask(255, 10)
    loose = solve_episode(g, 0, 7)
    cache = OptimumCache.in_memory(grid_map)
    cache.put((0, 0), 7, type(loose)(loose.actions, loose.seen, loose.seen + 1, "feasible", 0.0),
              1.0, 1, "HiGHS 1.16.0")  # fmt: skip
    [entry] = close_gaps(grid_map, np.array([[0, 0]]), np.array([7]),
                         SearchOptions(time_limit_s=1e-9, key_targets=6), cache)  # fmt: skip
    assert entry["status"] == "feasible" and entry["bound"] == loose.seen + 1
    with pytest.raises(ValueError, match="time limit"):
        SearchOptions(time_limit_s=float("nan"))
    with pytest.raises(ValueError, match="key targets"):
        SearchOptions(key_targets=0)
