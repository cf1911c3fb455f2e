"""A beam-search planner: the strong yardstick for learned agents.

It searches over action sequences breadth-first, keeping per episode the ``width`` partial paths
that have seen the most target cells, and pruning every path that could no longer get home and
land. The best landed path found is the plan. Coverage is held as packed bits (popcount), and all
episodes of a protocol are searched together, so a full protocol takes seconds.

The safe greedy planner's path is kept as the incumbent: where it sees more than the beam's best,
it is the plan, so this planner is never worse than greedy. Because the grid is deterministic a
plan made at the first step is simply followed; if the observed state ever departs from the
plan's (e.g. under the physics backend) that episode is replanned from where it is.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.graph import MapGraph, graph_from_observation
from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.planners.rollout import decode_observation, rollout
from cpp_mujoco.planners.safe_greedy import SafeGreedyPlanner

_MIX = np.uint64(0x9E3779B97F4A7C15)


def _pack(mask: np.ndarray) -> np.ndarray:
    """(..., C) bool → (..., ceil(C/64)) uint64 bitsets."""
    cells = mask.shape[-1]
    words = -(-cells // 64)
    padded = np.zeros((*mask.shape[:-1], words * 64), dtype=bool)
    padded[..., :cells] = mask
    return np.packbits(padded, axis=-1, bitorder="little").view(np.uint64)


def _popcount(bits: np.ndarray) -> np.ndarray:
    return np.bitwise_count(bits).sum(axis=-1, dtype=np.int64)


def _unpack(bits: np.ndarray, cells: int) -> np.ndarray:
    """Inverse of :func:`_pack`: (..., words) uint64 → (..., cells) bool."""
    flat = np.unpackbits(bits.view(np.uint8), axis=-1, bitorder="little")
    return flat[..., :cells].astype(bool)


def _group_rank(group: np.ndarray, keys: tuple[np.ndarray, ...]) -> np.ndarray:
    """Rank of each element within its group under ``keys`` (last key most significant)."""
    order = np.lexsort((*keys, group))
    sorted_group = group[order]
    starts = np.r_[0, np.flatnonzero(sorted_group[1:] != sorted_group[:-1]) + 1]
    first = np.repeat(starts, np.diff(np.r_[starts, group.size]))
    rank = np.empty(group.size, dtype=np.int64)
    rank[order] = np.arange(group.size) - first
    return rank


_CHUNK_BYTES = 64 << 20  # rough bound on one chunk's beam of packed coverage

# (cells (R,), budgets left (R,), coverage (R, H·W) bool) of R beam rows → (R, 5) how many more
# target cells each action is worth from there (a learned value, :mod:`cpp_mujoco.agent.value_beam`)
ActionValues = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def plan_paths(
    g: MapGraph,
    pos: np.ndarray,
    budget: np.ndarray,
    coverage: np.ndarray,
    width: int,
    values: ActionValues | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Best landed action sequence per episode: (actions (k, T) padded with LAND, lengths (k,)).

    ``values``: the exploring half of the beam keeps the paths with the most targets seen plus
    ``values`` of the move that made them (else: most seen, then nearest to unseen targets).
    Episodes are searched independently, so they are planned in chunks whose beams (each row
    a packed coverage bitset of the map) fit in ``_CHUNK_BYTES``; results do not depend on it.
    """
    words = -(-g.num_cells // 64) * (2 if values else 1)  # values read the whole coverage too
    chunk = max(1, _CHUNK_BYTES // (4 * LAND * width * words * 8))  # ~4 copies of 4·width rows
    if pos.size <= chunk:
        return _plan_chunk(g, pos, budget, coverage, width, values)
    parts = [
        _plan_chunk(
            g, pos[i : i + chunk], budget[i : i + chunk], coverage[i : i + chunk], width, values
        )
        for i in range(0, pos.size, chunk)
    ]
    steps = max(a.shape[1] for a, _ in parts)
    actions = [np.pad(a, ((0, 0), (0, steps - a.shape[1])), constant_values=LAND) for a, _ in parts]
    return np.concatenate(actions), np.concatenate([n for _, n in parts])


def _plan_chunk(
    g: MapGraph,
    pos: np.ndarray,
    budget: np.ndarray,
    coverage: np.ndarray,
    width: int,
    values: ActionValues | None,
) -> tuple[np.ndarray, np.ndarray]:
    k = pos.size
    fov_bits = g.fov_target_bits
    target = g.grid_map.target.reshape(-1)
    lands = g.safety.accepted[:, LAND]
    toward_targets = g.toward_targets
    # the beam: one row per partial path
    ep = np.arange(k)
    cur = pos.copy()
    left = budget.copy()
    bits = _pack(coverage & target)
    seen = _pack(coverage) if values else None  # every cell seen: what a network reads
    history: list[tuple[np.ndarray, np.ndarray]] = []  # (parent row, action) per depth
    best_value = np.full(k, -1, dtype=np.int64)
    best_depth = np.zeros(k, dtype=np.int64)
    best_row = np.zeros(k, dtype=np.int64)
    for depth in range(int(budget.max()) + 1):
        # landing here ends a path: its value is what it has seen (the land step sees FoV too)
        can_land = lands[cur] & (left >= 1)
        value = np.where(can_land, _popcount(bits | fov_bits[cur]), -1)
        order = np.lexsort((-value, ep))  # best value first within each episode
        first = order[np.r_[True, ep[order][1:] != ep[order][:-1]]]
        improved = value[first] > best_value[ep[first]]
        winners = first[improved]
        best_value[ep[winners]] = value[winners]
        best_depth[ep[winners]] = depth
        best_row[ep[winners]] = winners
        # expand by the four moves, keeping paths that can still get home
        parent = np.repeat(np.arange(cur.size), LAND)
        action = np.tile(np.arange(LAND), cur.size)
        nxt = g.safety.next_cell[cur[parent], action]
        keep = g.safety.accepted[cur[parent], action] & (left[parent] - 1 >= g.home[nxt])
        parent, action, nxt = parent[keep], action[keep], nxt[keep]
        if parent.size == 0:
            break
        new_bits = bits[parent] | fov_bits[nxt]
        score = _popcount(new_bits)
        if values:
            worth = values(cur, left, _unpack(seen, g.num_cells))[parent, action]
            estimate = _popcount(bits)[parent] + worth
        new_ep = ep[parent]
        key = nxt.astype(np.uint64) * _MIX
        for w in range(new_bits.shape[1]):
            key = (key ^ new_bits[:, w]) * _MIX
        # drop duplicate states (same episode, cell and coverage)
        order = np.lexsort((key, new_ep))
        dup = np.r_[
            False, (new_ep[order][1:] == new_ep[order][:-1]) & (key[order][1:] == key[order][:-1])
        ]
        order = order[~dup]
        # keep the best `width` per episode, half ranked for exploring (most seen, then nearest
        # to unseen targets), half for returning (most seen, then nearest to a landing cell):
        # ranking on coverage alone fills the beam with paths that can never get home in time
        cells, ep_u, score_u = nxt[order], new_ep[order], score[order]
        ahead = -estimate[order] if values else -score_u
        explore = _group_rank(ep_u, (toward_targets[cells], ahead))
        ret = _group_rank(ep_u, (g.home[cells], -score_u))
        order = order[(explore < width - width // 2) | (ret < width // 2)]
        history.append((parent[order], action[order]))
        if values:
            seen = seen[parent[order]] | g.fov_view_bits[nxt[order]]
        ep, cur, left, bits = new_ep[order], nxt[order], left[parent[order]] - 1, new_bits[order]
    # backtrack each episode's best landed path
    length = best_depth + 1
    actions = np.full((k, int(length.max())), LAND, dtype=np.int64)
    row = best_row.copy()
    for depth in range(int(best_depth.max()), 0, -1):
        active = best_depth >= depth
        parents, acts = history[depth - 1]
        actions[active, depth - 1] = acts[row[active]]
        row[active] = parents[row[active]]
    return actions, length


class _Replay:
    """A policy that replays fixed action sequences, one column per call."""

    def __init__(self, actions: np.ndarray):
        self.actions, self.t = actions, 0

    def act(self, obs) -> np.ndarray:
        column = self.actions[:, min(self.t, self.actions.shape[1] - 1)]
        self.t += 1
        return column


DEFAULT_WIDTH = 32  # the yardstick's width: a protocol of 16×16 maps in seconds


class BeamSearchPlanner:
    """Beam search of ``width`` paths per episode; results name a width other than the
    default (``beam-search[width 512]``), since coverage grows with it."""

    def __init__(self, width: int = DEFAULT_WIDTH, fov_side: int = 3):
        if isinstance(width, bool) or not isinstance(width, int) or width < 1:
            raise ValueError(f"beam width must be a positive integer, got {width!r}")
        self.width = width
        self.name = "beam-search" if width == DEFAULT_WIDTH else f"beam-search[width {width}]"
        self.fov_side = fov_side
        self._plans: np.ndarray | None = None  # (N, T) actions
        self._pos: np.ndarray | None = None  # (N, T) expected position before each action
        self._budget: np.ndarray | None = None  # (N, T) expected budget before each action
        self._cursor = np.zeros(0, dtype=np.int64)
        self._length = np.zeros(0, dtype=np.int64)

    def reset(self, num_episodes: int, seed: int | None = None) -> None:
        """New episodes start: drop every plan (a finished plan would otherwise land at once)."""
        self._plans = self._pos = self._budget = None
        self._cursor = np.zeros(0, dtype=np.int64)
        self._length = np.zeros(0, dtype=np.int64)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        g = graph_from_observation(obs, self.fov_side)
        pos, budget, coverage = decode_observation(obs)
        n = pos.size
        if self._plans is None or self._plans.shape[0] != n:
            self._store(np.arange(n), *self._search(g, pos, budget, coverage), n=n)
        rows = np.arange(n)
        cursor = np.minimum(self._cursor, self._plans.shape[1] - 1)
        on_plan = (self._pos[rows, cursor] == pos) & (self._budget[rows, cursor] == budget)
        finished = (self._cursor >= self._length) | (budget <= 0)  # ended: nothing to replan
        stale = np.flatnonzero(~on_plan & ~finished)
        if stale.size:
            self._store(stale, *self._search(g, pos[stale], budget[stale], coverage[stale]), n=n)
            cursor = np.minimum(self._cursor, self._plans.shape[1] - 1)
        self._cursor += 1
        return self._plans[rows, cursor]

    def _search(self, g, pos, budget, coverage):
        """The beam's plan, or the incumbent's where that sees more: never worse than it."""
        config = GridConfig(fov_side=self.fov_side)
        beam, beam_len = plan_paths(g, pos, budget, coverage, self.width, self._values(g))
        _, beam_seen, _ = rollout(g.grid_map, _Replay(beam), pos, budget, coverage, config)
        other, other_seen, other_len = rollout(
            g.grid_map, self._incumbent(), pos, budget, coverage, config
        )
        steps = max(beam.shape[1], other.shape[1])
        beam = np.pad(beam, ((0, 0), (0, steps - beam.shape[1])), constant_values=LAND)
        other = np.pad(other, ((0, 0), (0, steps - other.shape[1])), constant_values=LAND)
        use_other = other_seen > beam_seen
        actions = np.where(use_other[:, None], other, beam)
        length = np.where(use_other, other_len, beam_len)
        steps = actions.shape[1]
        positions = np.empty_like(actions)
        positions[:, 0] = pos
        for t in range(1, steps):
            positions[:, t] = g.safety.next_cell[positions[:, t - 1], actions[:, t - 1]]
        budgets = budget[:, None] - np.arange(steps)[None, :]
        return actions, positions, budgets, length

    def _values(self, g: MapGraph) -> ActionValues | None:
        """What ranks the exploring half of the beam (None: targets seen, then the nearest)."""
        return None

    def _incumbent(self):
        """The policy whose mission is kept where it sees more than the beam's: safe greedy."""
        return SafeGreedyPlanner(self.fov_side)

    def _store(self, rows, actions, positions, budgets, length, n: int) -> None:
        steps = actions.shape[1]
        if self._plans is None or self._plans.shape[0] != n:
            self._plans = np.full((n, steps), LAND, dtype=np.int64)
            self._pos = np.full((n, steps), -1, dtype=np.int64)
            self._budget = np.full((n, steps), -1, dtype=np.int64)
            self._cursor = np.zeros(n, dtype=np.int64)
            self._length = np.zeros(n, dtype=np.int64)
        if steps > self._plans.shape[1]:
            extra = steps - self._plans.shape[1]
            self._plans = np.pad(self._plans, ((0, 0), (0, extra)), constant_values=LAND)
            self._pos = np.pad(self._pos, ((0, 0), (0, extra)), constant_values=-1)
            self._budget = np.pad(self._budget, ((0, 0), (0, extra)), constant_values=-1)
        self._plans[rows] = LAND
        self._pos[rows] = -1
        self._budget[rows] = -1
        self._plans[rows, :steps] = actions
        self._pos[rows, :steps] = positions
        self._budget[rows, :steps] = budgets
        self._cursor[rows] = 0
        self._length[rows] = length
