"""The evaluation protocol and the reference planners' guarantees."""

import json

import numpy as np
import pytest

from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.planners import BeamSearchPlanner, RandomPlanner, SafeGreedyPlanner, make_planner
from cpp_mujoco.protocol.evaluate import coverage_upper_bound, evaluate


@pytest.fixture(scope="module")
def greedy_results():
    return {m: evaluate(SafeGreedyPlanner(), m) for m in "ABC"}


def test_protocol_covers_every_landing_cell_and_budget(greedy_results):
    for name, result in greedy_results.items():
        landing_cells = int(load_map(name).landing.sum())
        assert result.landed.size == landing_cells * 51
        table = result.per_budget
        assert [row["budget"] for row in table] == list(range(25, 76))
        assert all(row["episodes"] == landing_cells for row in table)


def test_safe_greedy_always_lands_and_covers(greedy_results):
    for result in greedy_results.values():
        assert result.landing_ratio == 1.0
        assert result.coverage_ratio > 0.7


def test_coverage_never_exceeds_the_upper_bound(greedy_results):
    for result in greedy_results.values():
        for row in result.per_budget:
            assert row["coverage_ratio"] <= row["upper_bound"] + 1e-9
        # coverage grows with budget
        cov = [row["coverage_ratio"] for row in result.per_budget]
        assert cov[-1] > cov[0]


def test_beam_search_lands_always_and_is_at_least_as_good_as_greedy(greedy_results):
    for name in "BC":
        beam = evaluate(BeamSearchPlanner(width=16), name)
        assert beam.landing_ratio == 1.0
        assert beam.coverage_ratio >= greedy_results[name].coverage_ratio - 0.01


def test_beam_width_is_named_and_checked():
    assert BeamSearchPlanner().name == "beam-search"
    wide = BeamSearchPlanner(width=64)
    assert wide.name == "beam-search[width 64]"
    assert evaluate(wide, "C", budgets=[30]).summary()["policy"] == "beam-search[width 64]"
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ValueError, match="beam width must be a positive integer"):
            BeamSearchPlanner(width=bad)


def test_random_planner_is_a_floor(greedy_results):
    result = evaluate(RandomPlanner(seed=0), "B")
    assert result.coverage_ratio < 0.2 < greedy_results["B"].coverage_ratio
    assert result.landing_ratio < 1.0


def test_beam_search_finds_the_optimal_path_on_a_corridor():
    # L . T T T . . : 7 actions (3 moves out, 3 back, land) see all three targets
    grid_map = GridMap.from_ascii(["L.TTT.."])
    result = evaluate(BeamSearchPlanner(width=8), grid_map, budgets=[6, 7, 8])
    by_budget = {row["budget"]: row for row in result.per_budget}
    assert by_budget[7]["coverage_ratio"] == 1.0 and result.landing_ratio == 1.0
    # with 6 actions the best is 2 moves out and back: sees (0,2),(0,3)
    assert by_budget[6]["coverage_ratio"] == pytest.approx(2 / 3)


def test_upper_bound_formula():
    # the corridor: with b actions the UAV can go (b-1)//2 cells out and still land
    grid_map = GridMap.from_ascii(["LTTTTTTTTT"])
    assert coverage_upper_bound(grid_map, 1) == pytest.approx(1 / 9)  # land at once: sees (0,1)
    assert coverage_upper_bound(grid_map, 3) == pytest.approx(2 / 9)  # one cell out and back
    assert coverage_upper_bound(grid_map, 7) == pytest.approx(4 / 9)
    assert coverage_upper_bound(grid_map, 100) == 1.0
    # the move count limits it too: 9 + 3·(b−2) cells on an open map
    open_map = GridMap.from_ascii(["L" + "T" * 29] * 30)
    assert coverage_upper_bound(open_map, 10) == pytest.approx((9 + 24) / 870)


def test_result_json_and_unknown_names(tmp_path, greedy_results):
    path = tmp_path / "r.json"
    greedy_results["C"].to_json(path)
    data = json.loads(path.read_text())
    assert data["landing_ratio"] == 1.0 and len(data["per_budget"]) == 51
    assert data["map"] == "C" and data["map_bundled"] is True
    assert data["map_digest"] == load_map("C").digest
    assert data["conditions"]["budgets"] == {"min": 25, "max": 75, "step": 1}
    assert data["conditions"]["episodes"] == 612 and data["conditions"]["backend"] == "grid"
    assert greedy_results["C"].grid_map.digest == load_map("C").digest
    with pytest.raises(ValueError, match="unknown planner"):
        make_planner("astar")
    with pytest.raises(ValueError, match="unknown backend"):
        evaluate(SafeGreedyPlanner(), "A", backend="unity")


def test_trajectories_start_on_landing_cells_and_end_with_minus_one(greedy_results):
    result = greedy_results["A"]
    first = result.trajectories[:, 0]
    assert load_map("A").landing.reshape(-1)[first].all()
    lengths = (result.trajectories >= 0).sum(axis=1)
    np.testing.assert_array_equal(lengths, result.steps + 1)
