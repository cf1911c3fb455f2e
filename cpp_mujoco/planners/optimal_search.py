"""An exact answer to the question the branch and cut finds hardest: can a mission of ``b`` units
see at least ``n`` target cells?

Where the solvers stop one target short of their bound, the episode asks exactly that, for the
bound's count. A depth-first search over (cell, targets seen) answers it: the mission, or a proof
that none exists. Three cuts make it finish. The *key-target table* holds, for every subset of ``k``
key targets and every cell, the fewest units to see them all and land — a shortest path over
(cell, key targets still unseen), exact for the key targets and so a lower bound for the mission
(with ``m`` targets allowed to stay unseen, the cheapest subset of the key targets short of up to
``m``). The *reach table* holds, per cell and units left, the targets seen from every cell the
UAV can still fly to and land from: a state that cannot see enough of them is cut. The
*transposition table* cuts a state (cell, targets seen) reached again with no fewer
units spent. Coverage follows the MDP: the view of the cell after each action (the landing's
included, the start's not at reset), from :class:`~cpp_mujoco.grid.graph.MapGraph`'s view table,
so obstacles hide what they hide. A hover after the first action repeats a view and is never
searched. The search runs in slices of nodes, so a time limit holds and the answer is ``unknown``
when it hits.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.graph import MapGraph

FAR = 255  # the key-target table's "never" (uint8); missions are shorter
_SLICE = 1 << 20  # nodes between looks at the clock


@dataclass(frozen=True)
class SearchOptions:
    """How hard the search works on one question."""

    time_limit_s: float = 600.0  # per question; the answer is "unknown" when it runs out
    key_targets: int = 20  # k: the key-target table has 2^k rows (fewer where memory says so)
    table_bytes: int = 256 << 20  # the most memory for the key-target table
    transposition_bits: int = 24  # 2^bits remembered states

    def __post_init__(self) -> None:
        if not np.isfinite(self.time_limit_s) or self.time_limit_s <= 0:
            raise ValueError(f"time limit must be a positive number, got {self.time_limit_s}")
        if not 1 <= self.key_targets <= 24:
            raise ValueError(f"key targets must be 1 to 24, got {self.key_targets}")
        if not 10 <= self.transposition_bits <= 30:
            raise ValueError(f"transposition bits must be 10 to 30, got {self.transposition_bits}")


@dataclass
class SearchAnswer:
    """``found``: ``actions`` (ending with the landing) see ``seen`` >= the asked count; ``none``:
    proven that no mission of the budget does; ``unknown``: the time limit came first."""

    status: str
    actions: np.ndarray
    seen: int
    nodes: int
    time_s: float


class CoverageSearch:
    """The tables of one map for one start's questions (the key targets are chosen far from each
    other and from the start, where a mission must go out of its way to see them)."""

    def __init__(self, g: MapGraph, start: int, options: SearchOptions | None = None):
        self.g, self.start = g, int(start)
        self.options = options = options or SearchOptions()
        n = g.num_cells
        self.targets = np.flatnonzero(g.grid_map.target.reshape(-1))
        index = np.full(n, -1, dtype=np.int64)
        index[self.targets] = np.arange(self.targets.size)
        words = max(1, -(-self.targets.size // 64))
        self.views = np.zeros((n, words), dtype=np.uint64)  # target bits each cell's view shows
        for j in range(g.fov_cells.shape[1]):
            on = g.fov_valid[:, j] & g.fov_targets[:, j]
            t = index[g.fov_cells[on, j]]
            np.bitwise_or.at(
                self.views, (np.flatnonzero(on), t >> 6), np.uint64(1) << (t & 63).astype(np.uint64)
            )
        k = min(options.key_targets, self.targets.size, int(np.log2(options.table_bytes // n)))
        self.keys = self._choose_keys(max(k, 0))
        t = index[self.keys]  # the key targets' bits, gathered from the views into k bits
        shown = (self.views[:, t >> 6] >> (t & 63).astype(np.uint64)) & np.uint64(1)
        self.key_views = shown.astype(np.int64) @ (1 << np.arange(t.size, dtype=np.int64))
        home = np.minimum(g.home, FAR).astype(np.int64)
        self.moves = g.safety.next_cell[:, :LAND].astype(np.int64)
        costs = _cover_costs(self.key_views, self.moves, g.safety.accepted, home, self.keys.size)
        self._misses = {0: costs}
        self._reach_table: np.ndarray | None = None

    @property
    def name(self) -> str:
        """The solver as the optimum cache names it (the first word tells it apart)."""
        return f"key-target search, {self.keys.size} key targets"

    def _choose_keys(self, k: int) -> np.ndarray:
        """k target cells, each the farthest (Chebyshev) from the start and those chosen before."""
        w = self.g.grid_map.shape[1]
        rows, cols = np.divmod(self.targets, w)
        sr, sc = divmod(self.start, w)
        far = np.maximum(abs(rows - sr), abs(cols - sc))
        chosen = []
        for _ in range(k):
            i = int(far.argmax())
            chosen.append(self.targets[i])
            far = np.minimum(far, np.maximum(abs(rows - rows[i]), abs(cols - cols[i])))
            far[i] = -1
        return np.array(chosen, dtype=np.int64)

    def missing(self, m: int) -> np.ndarray:
        """The key-target table when up to ``m`` targets may stay unseen."""
        m = min(m, self.keys.size)
        if m not in self._misses:
            self._misses[m] = _drop_one(self.missing(m - 1), self.keys.size)
        return self._misses[m]

    def _reach(self, budget: int) -> np.ndarray:
        """(H·W, budget + 1, words): the targets seen from the cells that a UAV at p with r units
        left can fly to and still land from (their views and nothing else can still be seen)."""
        if self._reach_table is None or self._reach_table.shape[1] <= budget:
            n = self.g.num_cells
            cost = self.g.distance_from(np.arange(n)).astype(np.int64) + self.g.home[None, :]
            self._reach_table = _reach_views(cost, self.views, budget)
        return self._reach_table

    def ask(self, budget: int, need: int) -> SearchAnswer:
        """Is there a mission of ``budget`` units from the start that sees ``need`` targets?"""
        if budget >= FAR:  # the key-target table's costs are bytes
            raise ValueError(f"the search takes budgets of at most {FAR - 1} units, got {budget}")
        began = time.perf_counter()
        if need > self.targets.size:
            return SearchAnswer("none", np.zeros(0, np.int64), 0, 0, 0.0)
        table, reach = self.missing(self.targets.size - need), self._reach(budget)
        state = _SearchState(self.views.shape[1], budget, 1 << self.options.transposition_bits)
        deadline = began + self.options.time_limit_s
        while True:
            done = _search(
                self.start, budget, need, self.views, self.key_views, table, reach, self.moves,
                self.g.safety.accepted, self.g.safety.lands, int(self.g.new_per_move), _SLICE,
                *state.arrays,
            )  # fmt: skip
            if done != 0 or time.perf_counter() > deadline:
                break
        elapsed, nodes = time.perf_counter() - began, int(state.counters[1])
        if done == 1:
            depth = int(state.counters[0])
            actions = np.r_[state.taken[:depth], LAND].astype(np.int64)
            seen, landed = self.g.fly(self.start, actions)
            if not landed or seen < need or actions.size > budget:
                raise RuntimeError(
                    f"the search's mission from cell {self.start} flies to {seen} targets "
                    f"(landed: {landed}, {actions.size} units), not the {need} it found"
                )
            return SearchAnswer("found", actions, seen, nodes, elapsed)
        status = "none" if done == 2 else "unknown"
        return SearchAnswer(status, np.zeros(0, np.int64), 0, nodes, elapsed)


class _SearchState:
    """The depth-first search's stack and transposition table, kept between slices."""

    def __init__(self, words: int, budget: int, size: int):
        depth = budget + 2
        self.taken = np.zeros(depth, dtype=np.int64)
        self.counters = np.zeros(3, dtype=np.int64)  # depth, nodes, started
        self.arrays = (
            np.zeros(depth, dtype=np.int64),  # cell
            np.zeros((depth, words), dtype=np.uint64),  # targets seen
            np.zeros(depth, dtype=np.int64),  # key targets seen
            np.zeros((depth, LAND + 1), dtype=np.int64),  # actions to try, best bound first
            np.zeros(depth, dtype=np.int64),  # how many
            np.zeros(depth, dtype=np.int64),  # next to try
            self.taken,
            np.full(size, -1, dtype=np.int64),  # remembered cell
            np.zeros((size, words), dtype=np.uint64),  # remembered targets seen
            np.zeros(size, dtype=np.int64),  # units spent when remembered
            self.counters,
        )


@njit(cache=True)
def _cover_costs(key_views, moves, accepted, home, k):
    """(2^k, H·W) uint8: fewest units to see the key targets of subset R (not yet seen) and land,
    from a cell whose view is already marked; :data:`FAR` where impossible.

    Subsets in increasing order (a move that shows some of R leads to a smaller subset, already
    done); within one subset a shortest path with unit moves through cells that show none of R
    (Dijkstra over buckets), from the cells one move from showing some."""
    n = key_views.size
    costs = np.full((1 << k, n), FAR, np.uint8)
    costs[0, :] = home
    dist = np.empty(n, np.int64)
    bucket = np.empty((FAR + 2, 5 * n), np.int64)
    filled = np.zeros(FAR + 2, np.int64)
    done = np.zeros(n, np.bool_)
    for subset in range(1, 1 << k):
        filled[:] = 0
        done[:] = False
        for p in range(n):
            best = FAR
            for a in range(moves.shape[1]):
                q = moves[p, a]
                if accepted[p, a] and key_views[q] & subset:
                    best = min(best, 1 + costs[subset & ~key_views[q], q])
            dist[p] = best
            if best < FAR:
                bucket[best, filled[best]] = p
                filled[best] += 1
        for v in range(FAR - 1):
            i = 0
            while i < filled[v]:
                p = bucket[v, i]
                i += 1
                if done[p] or dist[p] != v:
                    continue
                done[p] = True
                if key_views[p] & subset:
                    continue  # moving into p shows some of the subset: counted above
                for a in range(moves.shape[1]):
                    r = moves[p, a]  # moves are symmetric between flyable cells
                    if accepted[p, a] and not done[r] and dist[r] > v + 1:
                        dist[r] = v + 1
                        bucket[v + 1, filled[v + 1]] = r
                        filled[v + 1] += 1
        for p in range(n):
            costs[subset, p] = dist[p]
    return costs


@njit(cache=True)
def _reach_views(cost, views, budget):
    """[p, r]: the union of the views of the cells c with cost[p, c] <= r (cells by cost, their
    views accumulated)."""
    n, words = views.shape
    out = np.zeros((n, budget + 1, words), np.uint64)
    for p in range(n):
        order = np.argsort(cost[p])
        acc = np.zeros(words, np.uint64)
        i = 0
        for r in range(budget + 1):
            while i < n and cost[p, order[i]] <= r:
                for w in range(words):
                    acc[w] |= views[order[i], w]
                i += 1
            out[p, r, :] = acc
    return out


@njit(cache=True)
def _drop_one(costs, k):
    """The table when one more key target may stay unseen: each subset's cheapest with one fewer."""
    out = costs.copy()
    for subset in range(1, 1 << k):
        for t in range(k):
            bit = 1 << t
            if subset & bit:
                for p in range(costs.shape[1]):
                    if costs[subset ^ bit, p] < out[subset, p]:
                        out[subset, p] = costs[subset ^ bit, p]
    return out


@njit(cache=True)
def _count(bits):
    total = 0
    for w in range(bits.size):
        total += _bits(bits[w])
    return total


@njit(cache=True)
def _bits(x):
    total = 0
    while x:
        x &= x - np.uint64(1)
        total += 1
    return total


@njit(cache=True)
def _slot(cell, bits, size_bits):
    h = np.uint64(cell + 1) * np.uint64(0x632BE59BD9B4E019)
    for w in range(bits.size):
        h = (h ^ bits[w]) * np.uint64(0x9E3779B97F4A7C15)
    return int(h >> np.uint64(64 - size_bits))


@njit(cache=True)
def _search(start, budget, need, views, key_views, table, reach, moves, accepted, lands, per_move,
            max_nodes, cells, seen, keys, order, count, tried, taken, tt_cell, tt_seen, tt_spent,
            counters):  # fmt: skip
    """Up to ``max_nodes`` more nodes of the depth-first search; 1 found (the path in ``taken``,
    its length in ``counters[0]``), 2 none exists, 0 not done yet."""
    all_keys = np.int64(table.shape[0] - 1)
    size_bits = int(np.log2(tt_cell.size))
    words = views.shape[1]
    if counters[2] == 0:  # the root: at the start, nothing seen (its view is marked by an action)
        counters[2] = 1
        cells[0] = start
        seen[0, :] = 0
        keys[0] = 0
        count[0] = 0
        tried[0] = 0
        for a in range(LAND + 1):  # the first action may hover: it marks the start's view
            order[0, count[0]] = a
            count[0] += 1
    depth = counters[0]
    nodes = 0
    child = np.empty(words, np.uint64)
    bounds = np.empty(LAND, np.int64)
    while depth >= 0 and nodes < max_nodes:
        if tried[depth] >= count[depth]:
            depth -= 1
            continue
        a = order[depth, tried[depth]]
        tried[depth] += 1
        p = cells[depth]
        spent = depth + 1  # units after this action
        if a == LAND:
            if lands[p, LAND] and spent <= budget:
                for w in range(words):
                    child[w] = seen[depth, w] | views[p, w]
                if _count(child) >= need:
                    counters[0] = depth
                    counters[1] += nodes
                    return 1
            continue
        q = moves[p, a]
        for w in range(words):
            child[w] = seen[depth, w] | views[q, w]
        slot = _slot(q, child, size_bits)
        if tt_cell[slot] == q and tt_spent[slot] <= spent:
            same = True
            for w in range(words):
                if tt_seen[slot, w] != child[w]:
                    same = False
                    break
            if same:
                continue
        tt_cell[slot] = q
        tt_seen[slot, :] = child
        tt_spent[slot] = spent
        nodes += 1
        taken[depth] = a
        depth += 1
        cells[depth] = q
        seen[depth, :] = child
        keys[depth] = keys[depth - 1] | key_views[q]
        tried[depth] = 0
        count[depth] = 0
        missing = need - _count(child)
        # children: lands here, or moves whose bound fits the budget, best bound first
        if lands[q, LAND] and missing <= 0 and spent + 1 <= budget:
            order[depth, 0] = LAND
            count[depth] = 1
        for b in range(LAND):
            r = moves[q, b]
            bounds[b] = budget + 1
            if not accepted[q, b]:
                continue  # a hover repeats a view
            rest = 1 + table[all_keys & ~(keys[depth] | key_views[r]), r]
            if spent + rest > budget:
                continue
            gain = 0
            within = 0  # what can still be seen after the move: the view there and beyond
            for w in range(words):
                gain += _bits(views[r, w] & ~child[w])
                within += _bits(reach[r, budget - spent - 1, w] & ~child[w])
            if within < missing:
                continue
            left = missing - gain
            if left > 0:
                rest = max(rest, 1 + (left + per_move - 1) // per_move + 1)
            bounds[b] = spent + rest
        for _ in range(LAND):
            b = np.argmin(bounds)
            if bounds[b] > budget:
                break
            order[depth, count[depth]] = b
            count[depth] += 1
            bounds[b] = budget + 1
    counters[0] = depth
    counters[1] += nodes
    return 2 if depth < 0 else 0
