"""Shortest flight distances on a map, under the safety controller's rules.

A property of the map, not of a planner: the planners reason about reachability and the way home
with these tables, and the protocol's coverage upper bound needs the way home too. They are derived
from the same :class:`SafetyController` the MDP uses, so a planner can never plan a move the MDP
rejects.
Nothing is (cells × cells): distances from a cell are computed when asked for and kept in a
bounded cache, the field of view is an index table — a 128×128 map costs megabytes, not
gigabytes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.coverage import square_fov_counts, view_cells, view_counts
from cpp_mujoco.grid.return_rule import REJECTED_AFTER, paid_actions
from cpp_mujoco.grid.safety import SafetyController
from cpp_mujoco.maps import GridMap

UNREACHABLE = 10**6  # "no path"; two of them still add up inside int32
DISTANCE_DTYPE = np.int32
CACHE_BYTES = 32 << 20  # distance rows kept per map
_CHUNK_BYTES = 16 << 20  # scipy's float64 rows computed at once


def _as_steps(dist: np.ndarray) -> np.ndarray:
    return np.where(np.isfinite(dist), dist, UNREACHABLE).astype(DISTANCE_DTYPE)


def _distance_to_any(adjacency: csr_matrix, cells: np.ndarray) -> np.ndarray:
    """(H·W,): fewest accepted moves from each cell to the nearest of ``cells`` — one
    multi-source search over the reversed moves, exact for every cell."""
    dist = dijkstra(adjacency.T.tocsr(), indices=cells, unweighted=True, min_only=True)
    return _as_steps(dist)


class DistanceRows:
    """Rows ``d(p, ·)`` of the all-pairs table, computed on demand, least recently used dropped.

    At most ``max_bytes`` of rows are kept; a request for more distinct rows than that is
    computed in chunks and not cached, so memory stays bounded whatever the batch.
    """

    def __init__(self, adjacency: csr_matrix, max_bytes: int = CACHE_BYTES):
        self.adjacency = adjacency
        cells = adjacency.shape[0]
        row_bytes = cells * np.dtype(DISTANCE_DTYPE).itemsize
        self.capacity = int(min(cells, max(1, max_bytes // row_bytes)))
        self._table = np.empty((self.capacity, cells), dtype=DISTANCE_DTYPE)  # pages on use
        self._slot = np.full(cells, -1, dtype=np.intp)  # cell -> slot
        self._owner = np.full(self.capacity, -1, dtype=np.intp)  # slot -> cell
        self._stamp = np.zeros(self.capacity, dtype=np.int64)
        self._clock = 0

    def compute(self, cells: np.ndarray) -> np.ndarray:
        """(k, H·W) distances from ``cells``, uncached, in bounded chunks."""
        cells = np.asarray(cells, dtype=np.intp).reshape(-1)
        n = self.adjacency.shape[0]
        out = np.empty((cells.size, n), dtype=DISTANCE_DTYPE)
        chunk = max(1, _CHUNK_BYTES // (8 * n))
        for i in range(0, cells.size, chunk):
            part = dijkstra(self.adjacency, indices=cells[i : i + chunk], unweighted=True)
            out[i : i + chunk] = _as_steps(part)
        return out

    def slots(self, unique: np.ndarray) -> np.ndarray | None:
        """Cache slots holding the rows of the distinct ``unique`` cells; None if they can't fit."""
        if unique.size > self.capacity:
            return None
        self._clock += 1
        slot = self._slot[unique]
        missing = unique[slot < 0]
        if missing.size:
            self._stamp[slot[slot >= 0]] = self._clock  # keep what this request needs
            free = np.argsort(self._stamp, kind="stable")[: missing.size]
            evicted = self._owner[free]
            self._slot[evicted[evicted >= 0]] = -1
            self._table[free] = self.compute(missing)
            self._owner[free] = missing
            self._slot[missing] = free
            slot = self._slot[unique]
        self._stamp[slot] = self._clock
        return slot

    def rows(self, cells: np.ndarray) -> np.ndarray:
        """(k, H·W): ``d(cells[i], q)`` for every cell q."""
        cells = np.asarray(cells, dtype=np.intp).reshape(-1)
        unique, inverse = np.unique(cells, return_inverse=True)
        slot = self.slots(unique)
        if slot is None:
            return self.compute(unique)[inverse]
        return self._table[slot[inverse]]

    def pairs(self, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
        """``d(src[i], dst[i, j])`` for (k,) sources and (k, m) destinations."""
        src = np.asarray(src, dtype=np.intp).reshape(-1)
        unique, inverse = np.unique(src, return_inverse=True)
        slot = self.slots(unique)
        if slot is None:
            return self.compute(unique)[inverse[:, None], dst]
        return self._table[slot[inverse][:, None], dst]


@dataclass(frozen=True, eq=False)
class MapGraph:
    """Per-map tables for planners (cells are flat indices ``row * W + col``).

    ``home[p]``: fewest actions from p to be landed (moves to a landing cell, plus the land).
    ``fov_cells[p]``/``fov_targets[p]``: the cells of p's field of view (side² entries) and which
    of them are targets (padding off the grid, and what obstacles hide, is never a target; see
    :func:`~cpp_mujoco.grid.coverage.view_cells`).
    ``distance_from(cells)``: fewest accepted moves from each cell to every cell (UNREACHABLE if
    none). The move graph is symmetric between cells that are not no-fly (a move p→q is accepted
    iff q is on the grid and not no-fly, and the UAV is never on a no-fly cell), so
    ``d(q, goal) = distance_from(goal)[q]`` — one cache serves both directions.
    """

    grid_map: GridMap
    safety: SafetyController
    adjacency: csr_matrix
    home: np.ndarray
    fov_side: int
    fov_cells: np.ndarray
    fov_valid: np.ndarray
    fov_targets: np.ndarray
    distances: DistanceRows = field(repr=False)

    @property
    def num_cells(self) -> int:
        return self.grid_map.landing.size

    def distance_from(self, cells) -> np.ndarray:
        """(k, H·W) int32: fewest accepted moves from ``cells[i]`` to each cell."""
        return self.distances.rows(cells)

    def distance_between(self, src, dst) -> np.ndarray:
        """(k, m) int32: fewest accepted moves from ``src[i]`` to ``dst[i, j]``."""
        return self.distances.pairs(src, dst)

    @cached_property
    def home_after(self) -> np.ndarray:
        """(H·W, 5): actions still needed to be landed after taking action a in cell p — 0 if it
        lands, else ``home`` of the cell it leads to; :data:`REJECTED_AFTER` (never paid) for an
        action the safety controller rejects: it only hovers, costing a unit for nothing, and a
        greedy policy that picks it once picks it again in the same state until the budget is
        spent (measured: the general agent hovered on a landing cell for 70 of 75 units)."""
        after = self.home[self.safety.next_cell]
        after[self.safety.lands] = 0
        after[~self.safety.accepted] = REJECTED_AFTER
        after.flags.writeable = False
        return after

    def safe_actions(self, cells, budget) -> np.ndarray:
        """(N, 5) bool: the actions after which the way home is still paid — the remaining
        budget after the action (every action costs one unit) covers :attr:`home_after`.

        The return rule of the safe greedy planner (its invariant ``budget >= home[p]``) as an
        action set, among the actions the safety controller accepts: in a state that keeps the
        invariant some action is always safe (the land on a landing cell, else the move one step
        nearer home), so a policy choosing only among these lands every calm-air episode."""
        return paid_actions(self.home_after[np.asarray(cells).reshape(-1)], budget)

    @cached_property
    def toward_targets(self) -> np.ndarray:
        """(H·W,): fewest moves to a cell from which some target cell is seen."""
        return _distance_to_any(self.adjacency, np.flatnonzero(self.fov_targets.any(axis=1)))

    @cached_property
    def fov_target_bits(self) -> np.ndarray:
        """(H·W, ceil(H·W/64)) uint64: bit q of row p set iff target cell q is seen from p.

        Cells × words (the beam search's popcount form), built from the index table.
        """
        return self._view_bits(self.fov_targets)

    @cached_property
    def fov_view_bits(self) -> np.ndarray:
        """As :attr:`fov_target_bits`, every cell the MDP marks seen from p: the coverage layer
        a network reads (a hidden or off-grid entry of the view table points at p itself)."""
        return self._view_bits(np.ones_like(self.fov_valid))

    def _view_bits(self, which: np.ndarray) -> np.ndarray:
        n = self.num_cells
        bits = np.zeros((n, -(-n // 64)), dtype=np.uint64)
        owner = np.arange(n)
        for k in range(self.fov_cells.shape[1]):  # one entry per row each time: no collisions
            on = which[:, k]
            q = self.fov_cells[on, k]
            bits[owner[on], q >> 6] |= np.left_shift(np.uint64(1), (q & 63).astype(np.uint64))
        return bits

    def fly(
        self, start: int, actions: np.ndarray, seen: np.ndarray | None = None
    ) -> tuple[int, bool]:
        """(target cells seen, landed) after ``actions`` from flat cell ``start`` under the MDP's
        rules, ``seen`` (H·W bool) the cells seen before: one mission checked, as the exact
        planner and the optimum cache check theirs."""
        covered = np.zeros(self.num_cells, dtype=bool) if seen is None else seen.copy()
        cell, landed = int(start), False
        for a in np.asarray(actions, dtype=np.int64):
            cell = int(self.safety.next_cell[cell, a])
            covered[self.fov_cells[cell][self.fov_valid[cell]]] = True
            if self.safety.lands[cell, a]:
                landed = True
                break
        return int((covered & self.grid_map.target.reshape(-1)).sum()), landed

    def new_targets_seen(self, unseen: np.ndarray) -> np.ndarray:
        """(N, H·W) int32: of the (N, H·W) bool ``unseen`` target cells, how many each cell sees."""
        if self.grid_map.has_obstacles:  # the view table (its targets: ``unseen`` are targets)
            return view_counts(unseen, self.fov_cells, self.fov_targets)
        return square_fov_counts(unseen, self.grid_map.shape, self.fov_side)

    @cached_property
    def new_per_move(self) -> int:
        """At most how many cells one move brings into view: ``fov_side`` (a new row or column
        of the square), more where obstacles hid cells of the old square that the new cell
        sees. Bounds count ``fov_side² + new_per_move · (moves − 1)`` seen cells."""
        if not self.grid_map.has_obstacles:
            return self.fov_side
        cells = self.fov_cells
        most = 0
        for a in range(LAND):
            src = np.flatnonzero(self.safety.accepted[:, a])
            dst = self.safety.next_cell[src, a]
            for part in np.array_split(np.arange(src.size), max(1, src.size // 4096)):
                p, q = src[part], dst[part]
                old = (cells[q][:, :, None] == cells[p][:, None, :]).any(axis=2)
                new = (self.fov_valid[q] & ~old).sum(axis=1)
                most = max(most, int(new.max(initial=0)))
        return max(self.fov_side, most)

    def returnable_goals(
        self, cells: np.ndarray, budget: np.ndarray, coverage: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(gain, dist, goal), each (N, H·W), for N UAVs at flat ``cells`` with ``budget`` left
        and ``coverage`` (N, H·W) bool: the unseen targets each cell shows, the fewest moves to
        it, and whether it shows one *and* can be reached and left for home within the budget.
        The safe greedy planner heads for these goals and lands when there are none; the
        general agent's finish mask forbids the landing while there are some — one rule."""
        unseen = ~coverage & self.grid_map.target.reshape(-1)
        gain = self.new_targets_seen(unseen)
        dist = self.distance_from(cells)
        goal = (dist > 0) & (dist + self.home[None, :] <= budget[:, None]) & (gain > 0)
        return gain, dist, goal


def build_graph(grid_map: GridMap, fov_side: int = 3) -> MapGraph:
    safety = SafetyController(grid_map)
    cells = grid_map.landing.size
    moves = safety.accepted[:, :LAND]
    src = np.repeat(np.arange(cells), LAND)[moves.reshape(-1)]
    dst = safety.next_cell[:, :LAND][moves]
    adjacency = csr_matrix((np.ones(src.size), (src, dst)), shape=(cells, cells))
    fov_cells, fov_valid = view_cells(grid_map, fov_side)
    fov_targets = fov_valid & grid_map.target.reshape(-1)[fov_cells]
    to_landing = _distance_to_any(adjacency, np.flatnonzero(grid_map.landing))
    home = np.minimum(to_landing + 1, UNREACHABLE)  # + the land; "no way home" stays UNREACHABLE
    return MapGraph(
        grid_map, safety, adjacency, home, fov_side, fov_cells, fov_valid, fov_targets,
        DistanceRows(adjacency),
    )  # fmt: skip


# a general agent's guide asks for 10–16 maps per step: 4 rebuilt every graph (18 ms a step);
# a 32×32 graph holds at most 4 MB of distance rows, usually far less
@lru_cache(maxsize=32)
def _graph_from_bytes(layers: bytes, shape: tuple[int, ...], fov_side: int) -> MapGraph:
    arr = np.frombuffer(layers, dtype=np.int8).reshape(shape).astype(bool)
    obstacle = arr[3] if shape[0] > 3 else None
    return build_graph(
        GridMap(landing=arr[0], target=arr[1], nfz=arr[2], obstacle=obstacle, name="observed"),
        fov_side,
    )


def graph_from_observation(obs: dict[str, np.ndarray], fov_side: int = 3) -> MapGraph:
    """The graph of the map inside a (batched) observation (its ``obstacle`` layer, where the
    observation has one, included); cached per map."""
    layers = np.asarray(obs["map"])
    obstacle = obs.get("obstacle")
    if layers.ndim == 4:
        layers = layers[0]
        obstacle = None if obstacle is None else np.asarray(obstacle)[0]
    if obstacle is not None and np.any(obstacle):
        layers = np.concatenate([layers, np.asarray(obstacle)[None]], axis=0)
    layers = np.ascontiguousarray(layers, dtype=np.int8)
    return _graph_from_bytes(layers.tobytes(), layers.shape, fov_side)


def coverage_upper_bound(grid_map: GridMap, budget: int, fov_side: int = 3) -> float:
    """An upper bound on the coverage ratio any policy reaches with ``budget`` actions."""
    return coverage_upper_bounds(grid_map, [budget], fov_side)[budget]


def coverage_upper_bounds(
    grid_map: GridMap, budgets: Iterable[int], fov_side: int = 3
) -> dict[int, float]:
    """Budget → an upper bound on the coverage ratio any policy reaches with that many actions.

    min(targets visible from cells it can visit and still land, cells a path can see) / targets.
    A visited cell c needs ``2·d(c) + 1 <= budget`` (out from a landing cell, back, land), with
    d the flight distance to the landing zone; the path sees at most ``fov_side²`` cells at its
    first step and ``new_per_move`` new cells per further move (one action is the landing).
    """
    g = build_graph(grid_map, fov_side)  # one way-home table for every budget
    bounds = {}
    for budget in {int(b) for b in budgets}:
        visitable = 2 * (g.home - 1) + 1 <= budget
        seen = np.zeros(g.num_cells, dtype=bool)
        seen[g.fov_cells[visitable][g.fov_targets[visitable]]] = True
        visible = int(seen.sum())
        seeable = fov_side**2 + g.new_per_move * max(budget - 2, 0)
        bounds[budget] = float(min(visible, seeable) / grid_map.target.sum())
    return bounds
