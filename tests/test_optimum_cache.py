"""The optimum cache keeps its entries consistent with each other: a smaller budget's mission
flies with a larger one, a neighbouring landing cell's after the flight between them, and the
bounds likewise."""

import numpy as np
import pytest

from cpp_mujoco.grid.graph import build_graph
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.protocol.optimum import default_folder
from cpp_mujoco.protocol.optimum_cache import CacheError, OptimumCache, tighten

N, E, S, W, LAND = 0, 1, 2, 3, 4
PATCH = GridMap.from_ascii("LL..T\n.....\nT...T")
G = build_graph(PATCH, 3)


def entry(seen, bound, status, actions, solver="HiGHS 1.16.0"):
    return {
        "seen": seen, "bound": bound, "status": status, "time_s": 1.0, "time_limit_s": 10.0,
        "workers": 1, "solver": solver, "actions": actions,
    }  # fmt: skip


def flown(start: int, actions: list[int]) -> int:
    seen, landed = G.fly(start, np.array(actions))
    assert landed
    return seen


def test_missions_climb_and_bounds_fall_across_budgets_and_landing_cells():
    tour = [E, E, E, S, W, W, W, N, LAND]  # from (0, 1): the east column, back along row 1
    assert flown(1, tour) == 3  # every target
    entries = {
        "0,1,9": entry(3, 4, "feasible", tour),
        "0,1,10": entry(1, 9, "feasible", [S, N, LAND]),  # worse than the smaller budget's
        "0,0,10": entry(1, 9, "feasible", [S, N, LAND]),  # (0, 1)'s tour flies from here too
        "0,0,11": entry(0, 9, "unknown", []),
        "0,1,12": entry(3, 3, "optimal", tour),  # proves 3 for (0, 1) up to 12, (0, 0) to 11
        "0,0,7": entry(0, 0, "infeasible", []),  # the tour needs 10 units from (0, 0)
    }
    assert tighten(entries, G) == 4
    assert entries["0,1,9"] == {**entry(3, 3, "optimal", tour),
                                "tightened_from": {"bound": "0,1,12"}}  # fmt: skip
    assert entries["0,1,10"]["actions"] == tour and entries["0,1,10"]["status"] == "optimal"
    assert entries["0,1,10"]["tightened_from"] == {"mission": "0,1,9", "bound": "0,1,12"}
    for key in ("0,0,10", "0,0,11"):  # the flight to (0, 1) first
        assert entries[key]["actions"] == [E, *tour] and entries[key]["status"] == "optimal"
        assert entries[key]["seen"] == flown(0, [E, *tour]) == 3
        assert entries[key]["tightened_from"] == {"mission": "0,1,9", "bound": "0,1,12"}
    assert entries["0,0,7"]["status"] == "infeasible" and "tightened_from" not in entries["0,1,12"]
    assert tighten(entries, G) == 0  # consistent now: nothing more to change


def test_a_cache_that_contradicts_itself_is_refused():
    tour = [E, E, E, S, W, W, W, N, LAND]
    entries = {"0,1,9": entry(3, 3, "optimal", tour), "0,0,11": entry(1, 2, "feasible", [S])}
    contradiction = r"contradicts itself at episode 0,1,9: .*bound is 2 .*0,0,11"
    with pytest.raises(CacheError, match=contradiction):
        tighten(entries, G)
    entries = {"0,1,9": entry(3, 3, "optimal", tour), "0,0,10": entry(0, 0, "infeasible", [])}
    with pytest.raises(CacheError, match=r"0,0,10: it has no way home"):
        tighten(entries, G)


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
        seen, landed = g.fly(row * width + col, actions, np.zeros(g.num_cells, bool))
        assert landed and actions.size <= budget and seen == e["seen"] <= e["bound"]
    # and the file is consistent: tightening it again changes nothing
    assert tighten(dict(cache.entries), g) == 0
