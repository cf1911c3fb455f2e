"""The progress mask: which moves it keeps, cell by cell and against a straightforward
breadth-first implementation; that it never removes the optimum's move (exhaustive search on
small maps); that a dead end takes the return rule's progress moves; that results name it."""

from collections import deque
from functools import cache

import numpy as np
import pytest

from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.rules import make_rules, rules_identity
from cpp_mujoco.agent.rules.progress_mask import PROGRESS_RULE, progress_allowed, progress_moves
from cpp_mujoco.grid.actions import LAND, MOVES
from cpp_mujoco.grid.graph import build_graph
from cpp_mujoco.maps import GridMap
from tests.hand_observations import hand_observation

ALL = np.ones((1, 5), dtype=bool)
POCKET = [(3, 1), (3, 3), (4, 1), (4, 3)]  # no-fly walls of a pocket (3..4, 2) open to the north


def test_in_a_pocket_only_the_way_out_is_kept():
    # the UAV at (3, 2) in the pocket; the target (0, 4) is first seen from (1, 3)
    obs = hand_observation(cell=(3, 2), landing=[(2, 2)], targets=[(0, 4)], nfz=POCKET)
    north, east, south, west, land = progress_moves(obs)[0]
    assert north and land and not (east or south or west)  # walls hover: nearer nothing
    # no goal left (seen, or out of the budget's reach): every action stays
    seen = hand_observation(cell=(3, 2), landing=[(2, 2)], targets=[(0, 4)], covered=[(0, 4)])
    assert progress_moves(seen).all()
    short = hand_observation(cell=(3, 2), landing=[(2, 2)], targets=[(0, 4)], budget=5)
    assert progress_moves(short).all()  # 3 moves there, 2 home and the landing: 6 > 5


def test_goals_on_both_sides_keep_both_ways():
    walls = [(0, c) for c in range(7)] + [(2, c) for c in range(7)]  # a corridor, row 1
    obs = hand_observation(3, 7, cell=(1, 3), landing=[(1, 3)], targets=[(1, 0), (1, 6)], nfz=walls)
    assert progress_moves(obs).tolist() == [[False, True, False, True, True]]
    one_side = hand_observation(
        3, 7, cell=(1, 3), landing=[(1, 3)], targets=[(1, 0), (1, 6)], nfz=walls, covered=[(1, 6)]
    )
    assert progress_moves(one_side).tolist() == [[False, False, False, True, True]]


def test_a_row_left_with_only_pruned_moves_takes_the_floors_way_out():
    obs = hand_observation(cell=(3, 2), landing=[(2, 2)], targets=[(0, 4)], nfz=POCKET)
    south_only = np.array([[False, False, True, False, False]])  # e.g. the revisit mask's choice
    assert progress_allowed(obs, south_only, ALL).tolist() == [[True, False, False, False, False]]
    # the floor (the return rule) forbids the way out too: the row keeps what it had
    floor = np.array([[False, False, True, False, True]])
    assert progress_allowed(obs, south_only, floor).tolist() == south_only.tolist()
    assert progress_allowed(obs, ALL, ALL).tolist() == [[True, False, False, False, True]]


def _random_map(rng, h, w) -> GridMap:
    while True:
        nfz = rng.random((h, w)) < 0.2
        landing = np.zeros((h, w), dtype=bool)
        free = np.flatnonzero(~nfz.reshape(-1))
        if free.size < 4:
            continue
        landing.reshape(-1)[rng.choice(free, rng.integers(1, 3), replace=False)] = True
        target = (rng.random((h, w)) < 0.45) & ~landing
        if target.any():
            return GridMap(landing=landing, target=target, nfz=nfz, name="random")


def _observation(grid_map: GridMap, cells, budgets, coverage) -> dict[str, np.ndarray]:
    n = len(cells)
    h, w = grid_map.shape
    position = np.zeros((n, h * w), dtype=np.int8)
    position[np.arange(n), cells] = 1
    layers = np.stack([grid_map.landing, grid_map.target, grid_map.nfz]).astype(np.float32)
    return {
        "map": layers,
        "position": position.reshape(n, h, w),
        "coverage": np.asarray(coverage, dtype=np.int8).reshape(n, h, w),
        "budget": np.asarray(budgets, dtype=np.float32).reshape(n, 1),
    }


def _reference(grid_map: GridMap, cell: int, budget: int, coverage: np.ndarray) -> list[bool]:
    """The rule read straight: breadth-first distances, 3×3 views, one move at a time."""
    h, w = grid_map.shape

    def neighbours(p):
        r, c = divmod(p, w)
        for dr, dc in MOVES[:LAND]:
            q = (r + dr, c + dc)
            if 0 <= q[0] < h and 0 <= q[1] < w and not grid_map.nfz[q]:
                yield q[0] * w + q[1]

    def bfs(src):
        dist = {src: 0}
        todo = deque([src])
        while todo:
            p = todo.popleft()
            for q in neighbours(p):
                if q not in dist:
                    dist[q] = dist[p] + 1
                    todo.append(q)
        return dist

    landings = [p for p in range(h * w) if grid_map.landing.reshape(-1)[p]]
    home = {}
    for p in landings:
        for q, d in bfs(p).items():
            home[q] = min(home.get(q, 10**9), d + 1)
    unseen = grid_map.target & ~coverage.reshape(h, w)

    def shows(q):
        r, c = divmod(q, w)
        return unseen[max(r - 1, 0) : r + 2, max(c - 1, 0) : c + 2].any()

    here = bfs(cell)
    goals = [q for q, d in here.items() if d > 0 and d + home.get(q, 10**9) <= budget and shows(q)]
    if not goals:
        return [True] * 5
    out = []
    r, c = divmod(cell, w)
    for dr, dc in MOVES[:LAND]:
        q = (r + dr, c + dc)
        inside = 0 <= q[0] < h and 0 <= q[1] < w and not grid_map.nfz[q]
        after = bfs(q[0] * w + q[1]) if inside else here
        out.append(any(after.get(g, 10**9) < here[g] for g in goals))
    return out + [True]


def test_it_equals_a_straightforward_implementation_on_random_states():
    rng = np.random.default_rng(7)
    checked = pruned = 0
    for _ in range(12):
        grid_map = _random_map(rng, 6, 7)
        graph = build_graph(grid_map)
        free = np.flatnonzero(~grid_map.nfz.reshape(-1) & (graph.home < 10**6))
        n = 40
        cells = rng.choice(free, n)
        budgets = graph.home[cells] + rng.integers(0, 12, n)
        coverage = rng.random((n, grid_map.landing.size)) < rng.random((n, 1))
        got = progress_moves(_observation(grid_map, cells, budgets, coverage))
        for i in range(n):
            want = _reference(grid_map, int(cells[i]), int(budgets[i]), coverage[i])
            assert got[i].tolist() == want, (grid_map.nfz, cells[i], budgets[i])
        checked += n
        pruned += int((~got).sum())
    assert checked == 480 and pruned > 100  # both kinds of move were met


def _best_coverage(grid_map: GridMap, start: int, budget: int, masked: bool, pruned: list) -> int:
    """The most target cells any landed mission from ``start`` sees (exhaustive, memoised);
    ``masked``: only the moves the progress mask keeps, in every state (``pruned`` counts the
    accepted moves it drops)."""
    graph = build_graph(grid_map)
    n = grid_map.landing.size
    targets = grid_map.target.reshape(-1)
    views = [graph.fov_cells[p][graph.fov_valid[p]] for p in range(n)]
    view_bits = [sum(1 << int(q) for q in view if targets[q]) for view in views]

    @cache
    def best(cell: int, seen: int, left: int) -> float:
        value = bin(seen).count("1") if grid_map.landing.reshape(-1)[cell] else -np.inf
        if left <= 1:
            return value
        actions = np.ones(LAND, dtype=bool)
        if masked:
            coverage = np.array([(seen >> q) & 1 for q in range(n)], dtype=bool)
            actions = progress_moves(_observation(grid_map, [cell], [left], coverage[None]))[0]
            pruned.append(int((graph.safety.accepted[cell, :LAND] & ~actions[:LAND]).sum()))
        for a in np.flatnonzero(actions[:LAND]):
            nxt = int(graph.safety.next_cell[cell, a])
            value = max(value, best(nxt, seen | view_bits[nxt], left - 1))
        return value

    return best(start, view_bits[start], budget)


@pytest.mark.parametrize("seed", range(6))
def test_it_never_removes_the_optimums_move(seed):
    """Exhaustive search over every mission on small random maps: the best landed mission
    among the moves the mask keeps sees as many targets as the best among all moves."""
    rng = np.random.default_rng(100 + seed)
    grid_map = _random_map(rng, 5, 5)
    pruned: list[int] = []
    for start in np.flatnonzero(grid_map.landing.reshape(-1)):
        for budget in (6, 9, 12):
            full = _best_coverage(grid_map, int(start), budget, False, [])
            assert full >= 0  # a landed mission exists (the start is a landing cell)
            assert _best_coverage(grid_map, int(start), budget, True, pruned) == full
    assert sum(pruned) > 0  # the mask did drop moves on the way


def test_results_name_it_only_when_it_is_on():
    general = load_agent("general")
    assert "progress_mask" not in general.identity()  # results from before it stay the same
    rules = make_rules(["return-mask", "progress-mask"])
    assert [r.name for r in rules] == ["return-mask", "progress-mask"]
    assert rules_identity(rules)["progress_rule"] == PROGRESS_RULE
    flown = general.with_rules([*general.rule_names, "progress-mask"])
    assert flown.rule_names == ["return-mask", "revisit-mask", "finish-mask", "progress-mask"]
