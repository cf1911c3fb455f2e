"""Memory grows with the cells, not cells²: large maps run, and the planners decide exactly as the
dense (all-pairs) implementation they replace."""

import hashlib
import json
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.sparse.csgraph import shortest_path

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.coverage import (
    mark_fov,
    mark_seen,
    square_fov_cells,
    square_fov_counts,
    square_fov_masks,
    square_fov_union,
)
from cpp_mujoco.grid.graph import UNREACHABLE, DistanceRows, build_graph
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.planners import BeamSearchPlanner, SafeGreedyPlanner, beam_search, safe_greedy
from cpp_mujoco.planners.rollout import decode_observation
from cpp_mujoco.protocol.evaluate import coverage_upper_bounds, evaluate

ROOT = Path(__file__).resolve().parents[1]


def _random_map(seed: int, shape=(9, 11)) -> GridMap:
    rng = np.random.default_rng(seed)
    landing = np.zeros(shape, dtype=bool)
    landing[4:6, 1:3] = True
    nfz = (rng.random(shape) < 0.18) & ~landing
    target = rng.random(shape) < 0.35  # some on no-fly cells: seen only from beside
    target[0, -1] = True
    return GridMap(landing=landing, target=target, nfz=nfz, name=f"random{seed}")


class _Dense:
    """The old tables: all-pairs distances and (cells × cells) field-of-view masks."""

    def __init__(self, grid_map: GridMap, side: int = 3):
        g = build_graph(grid_map, side)
        dist = shortest_path(g.adjacency, method="D", unweighted=True)
        self.distance = np.where(np.isfinite(dist), dist, UNREACHABLE).astype(np.int64)
        landing = np.flatnonzero(grid_map.landing)
        self.home = np.minimum(self.distance[:, landing].min(axis=1) + 1, UNREACHABLE)
        self.fov_targets = square_fov_masks(grid_map, side) & grid_map.target.reshape(-1)
        self.toward_targets = self.distance[:, self.fov_targets.any(axis=1)].min(axis=1)
        self.g = g


class _DenseSafeGreedy:
    """The safe greedy planner as it was, on the dense tables: the reference decisions."""

    name = "dense-safe-greedy"

    def __init__(self, grid_map: GridMap):
        self.d = _Dense(grid_map)

    def act(self, obs):
        d, g = self.d, self.d.g
        pos, budget, coverage = decode_observation(obs)
        rows = np.arange(pos.size)
        unseen = (~coverage & g.grid_map.target.reshape(-1)).astype(np.float32)
        gain = unseen @ d.fov_targets.T.astype(np.float32)
        dist = d.distance[pos]
        reachable = (dist > 0) & (dist + d.home[None, :] <= budget[:, None]) & (gain > 0)
        score = np.where(reachable, gain / np.maximum(dist, 1), -1.0)
        goal = score.argmax(axis=1)
        has_goal = score[rows, goal] > 0
        neighbours = g.safety.next_cell[pos, :LAND]
        moves_ok = g.safety.accepted[pos, :LAND]
        toward_goal = moves_ok & (
            d.distance[neighbours, goal[:, None]] == dist[rows, goal][:, None] - 1
        )
        goal_move = np.where(toward_goal, gain[rows[:, None], neighbours] + 1, 0).argmax(axis=1)
        toward_home = moves_ok & (d.home[neighbours] == d.home[pos][:, None] - 1)
        home_move = toward_home.argmax(axis=1)
        on_landing = g.grid_map.landing.reshape(-1)[pos]
        return np.where(has_goal, goal_move, np.where(on_landing, LAND, home_move))


@pytest.mark.parametrize("name", ["B", "C", "random1", "random2"])
def test_tables_match_the_dense_ones_and_moves_are_symmetric(name):
    grid_map = _random_map(int(name[-1])) if name.startswith("random") else load_map(name)
    g, d = build_graph(grid_map), _Dense(grid_map)
    cells = np.arange(g.num_cells)
    rows = g.distance_from(cells)
    np.testing.assert_array_equal(rows, d.distance)  # exact, no-fly rows included
    np.testing.assert_array_equal(g.home, d.home)
    np.testing.assert_array_equal(g.toward_targets, d.toward_targets)
    np.testing.assert_array_equal(g.fov_target_bits, beam_search._pack(d.fov_targets))
    # the symmetry the safe greedy planner relies on: d(p, q) = d(q, p) off the no-fly cells
    free = ~grid_map.nfz.reshape(-1)
    np.testing.assert_array_equal(rows[np.ix_(free, free)], rows[np.ix_(free, free)].T)
    assert (rows[np.ix_(free, ~free)] == UNREACHABLE).all()  # nothing flies into no-fly
    pairs = g.distance_between(cells[free], np.tile(cells[free], (free.sum(), 1)))
    np.testing.assert_array_equal(pairs, rows[np.ix_(free, free)])


def test_distance_cache_stays_bounded_and_exact_when_evicting():
    grid_map = _random_map(6)
    d = _Dense(grid_map)
    cells = grid_map.landing.size
    rows = DistanceRows(d.g.adjacency, max_bytes=5 * cells * 4)  # room for 5 rows
    assert rows.capacity == 5
    rng = np.random.default_rng(0)
    for size in (1, 3, 5, 2, 9, 4, 5, 1, 7):  # 9 and 7 distinct sources overflow: uncached
        src = rng.integers(cells, size=size)
        np.testing.assert_array_equal(rows.rows(src), d.distance[src])
        dst = rng.integers(cells, size=(size, 4))
        np.testing.assert_array_equal(rows.pairs(src, dst), d.distance[src[:, None], dst])
        cached = np.flatnonzero(rows._slot >= 0)
        assert cached.size <= 5
        np.testing.assert_array_equal(rows._table[rows._slot[cached]], d.distance[cached])


@pytest.mark.parametrize("side", [1, 2, 3, 4])
def test_fov_index_table_marks_what_the_mask_marked(side):
    grid_map = _random_map(3)
    cells, valid = square_fov_cells(grid_map.shape, side)
    target = grid_map.target.reshape(-1)
    masks = square_fov_masks(grid_map, side)
    rng = np.random.default_rng(side)
    n = 40
    new_cov = rng.random((n, target.size)) < 0.3
    old_cov = new_cov.copy()
    for _ in range(6):
        pos = rng.integers(target.size, size=n)
        rows = np.flatnonzero(rng.random(n) < 0.7)
        active = np.zeros(n, dtype=bool)
        active[rows] = True
        got = mark_fov(new_cov, cells, valid & target[cells], pos, rows)
        want = mark_seen(old_cov, masks[pos] & active[:, None], target)
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(new_cov, old_cov)
    path = rng.integers(target.size, size=7)
    np.testing.assert_array_equal(
        square_fov_union(grid_map.shape, side, path), masks[path].any(axis=0)
    )
    unseen = rng.random((5, target.size)) < 0.5
    counts = square_fov_counts(unseen, grid_map.shape, side)
    np.testing.assert_array_equal(counts, unseen.astype(int) @ masks.T.astype(int))


@pytest.mark.parametrize("seed", [1, 2, 4])
def test_safe_greedy_decides_as_the_dense_implementation(seed, monkeypatch):
    grid_map = _random_map(seed)
    budgets = [6, 13, 24, 40]
    want = evaluate(_DenseSafeGreedy(grid_map), grid_map, budgets=budgets)
    monkeypatch.setattr(safe_greedy, "_CHUNK_ELEMENTS", 3 * grid_map.landing.size)  # chunks of 3
    got = evaluate(SafeGreedyPlanner(), grid_map, budgets=budgets)
    np.testing.assert_array_equal(got.trajectories, want.trajectories)
    np.testing.assert_array_equal(got.coverage, want.coverage)
    assert got.landed.all()


def test_beam_search_is_the_same_in_chunks(monkeypatch):
    grid_map = _random_map(5)
    budgets = [9, 20, 33]
    whole = evaluate(BeamSearchPlanner(width=8), grid_map, budgets=budgets)
    monkeypatch.setattr(beam_search, "_CHUNK_BYTES", 1)  # one episode per chunk
    chunked = evaluate(BeamSearchPlanner(width=8), grid_map, budgets=budgets)
    np.testing.assert_array_equal(chunked.trajectories, whole.trajectories)
    assert chunked.landed.all()


def test_upper_bounds_match_the_dense_formula():
    grid_map = _random_map(2)
    d = _Dense(grid_map)
    for budget, bound in coverage_upper_bounds(grid_map, [3, 7, 12, 30]).items():
        visible = d.fov_targets[2 * (d.home - 1) + 1 <= budget].any(axis=0).sum()
        seeable = 9 + 3 * max(budget - 2, 0)
        assert bound == min(visible, seeable) / grid_map.target.sum()


# Per-episode coverage and steps of the full protocol, recorded with the dense implementation.
_RECORDED = {
    ("A", "safe-greedy"): "68f4debe76ff0b64",
    ("B", "safe-greedy"): "ecee1d379be5773f",
    ("C", "safe-greedy"): "6714641ab744ad5b",
    ("B", "beam-search"): "ef314d4f9e8514c1",
    ("C", "beam-search"): "6714641ab744ad5b",
}


@pytest.mark.parametrize(("name", "planner"), sorted(_RECORDED))
def test_bundled_protocol_results_are_unchanged(name, planner):
    policy = SafeGreedyPlanner() if planner == "safe-greedy" else BeamSearchPlanner()
    result = evaluate(policy, name)
    digest = hashlib.sha256(result.coverage.astype(np.float64).tobytes())
    digest.update(result.steps.astype(np.int64).tobytes())
    assert digest.hexdigest()[:16] == _RECORDED[name, planner]


def _limit_address_space() -> None:  # a (cells²) regression fails fast instead of swapping
    resource.setrlimit(resource.RLIMIT_AS, (6 << 30, 6 << 30))


def test_128x128_map_runs_env_batch_and_planners_in_under_2_gb():
    out = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "peak_memory.py"), "--side", "128"],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=_limit_address_space,
        check=False,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    report = json.loads(out.stdout.strip().splitlines()[-1])
    print(report)
    assert report["safe-greedy_landed"] and report["beam-search_landed"]
    assert len(report["beam-search_coverage"]) == 4  # 2 start cells × 2 budgets
    assert report["peak_rss_mib"] < 2048
