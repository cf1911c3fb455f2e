"""The optimum cache keeps each start's entries consistent across budgets: a smaller budget's
mission flies with a larger one, a larger budget's bound holds for a smaller one."""

import numpy as np
import pytest

from cpp_mujoco.grid.graph import build_graph
from cpp_mujoco.maps import load_map
from cpp_mujoco.planners.optimal_model import fly
from cpp_mujoco.protocol.optimum import default_folder
from cpp_mujoco.protocol.optimum_cache import CacheError, OptimumCache, tighten_by_budget


def entry(seen, bound, status, actions, solver="HiGHS 1.16.0"):
    return {
        "seen": seen, "bound": bound, "status": status, "time_s": 1.0, "time_limit_s": 10.0,
        "workers": 1, "solver": solver, "actions": actions,
    }  # fmt: skip


def test_missions_climb_and_bounds_fall_across_budgets():
    entries = {
        "3,1,9": entry(0, 0, "infeasible", []),
        "3,1,10": entry(7, 9, "feasible", [0, 0, 4]),
        "3,1,11": entry(6, 9, "feasible", [1, 4]),  # worse than the smaller budget's mission
        "3,1,12": entry(8, 12, "feasible", [2, 2, 4]),
        "3,1,13": entry(8, 8, "optimal", [2, 2, 4]),  # proves 8 for every smaller budget
        "0,0,11": entry(5, 6, "feasible", [3, 4]),  # another start: left alone
    }
    assert tighten_by_budget(entries) == 3
    assert entries["3,1,9"]["status"] == "infeasible"
    assert entries["3,1,10"] == {**entry(7, 8, "feasible", [0, 0, 4]),
                                 "tightened_from": {"mission": 10, "bound": 13}}  # fmt: skip
    assert entries["3,1,11"]["actions"] == [0, 0, 4] and entries["3,1,11"]["seen"] == 7
    assert entries["3,1,11"]["tightened_from"] == {"mission": 10, "bound": 13}
    assert entries["3,1,12"]["status"] == "optimal" and entries["3,1,12"]["bound"] == 8
    assert "tightened_from" not in entries["3,1,13"] and "tightened_from" not in entries["0,0,11"]
    assert tighten_by_budget(entries) == 0  # consistent now: nothing more to change


def test_a_cache_that_contradicts_itself_is_refused():
    entries = {"3,1,10": entry(9, 9, "optimal", [0, 4]), "3,1,11": entry(7, 8, "feasible", [4])}
    with pytest.raises(CacheError, match=r"contradicts itself at start \(3, 1\)"):
        tighten_by_budget(entries)


@pytest.mark.parametrize("name", ["A", "B"])
def test_every_tightened_mission_of_the_committed_cache_flies_to_its_count(name):
    grid_map = load_map(name)
    g = build_graph(grid_map)
    width = grid_map.shape[1]
    cache = OptimumCache(default_folder(), grid_map)
    moved = {k: e for k, e in cache.entries.items() if "tightened_from" in e}
    assert moved  # the committed caches hold such entries
    for key, e in moved.items():
        row, col, budget = (int(v) for v in key.split(","))
        actions = np.array(e["actions"], dtype=np.int64)
        seen, landed = fly(g, row * width + col, actions, np.zeros(g.num_cells, bool))
        assert landed and actions.size <= budget and seen == e["seen"] <= e["bound"]
    # and the file is consistent: tightening it again changes nothing
    assert tighten_by_budget(dict(cache.entries)) == 0
