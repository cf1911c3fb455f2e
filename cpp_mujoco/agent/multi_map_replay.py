"""Replay memory and demonstrations over a pool of maps (:class:`MapPool`).

The per-map :class:`ReplayBuffer` stores its one map once. Here every stored state also keeps
its map's index in the pool, and coverage is kept as packed bits of the pool's padded layout
(128 bytes a state on 32×32, 8× less than bools), so a 200,000-transition memory takes about
35 MB. The n-step windows are read exactly as in :class:`ReplayBuffer` (inherited): a window ends
at a termination, and a slot changes map only when an episode ends, so no window spans two maps.
For a network with the obstacle input the states are rebuilt with their map's obstacle layer
(:meth:`MapPool.grids`): a property of the map, so nothing more is stored per state.

Demonstrations (DQfD) are recorded map by map with the per-map recorder, then kept compact: each
recorded state once, and per transition its n-step return, discount and the index of its
bootstrap state (:func:`record_pool_demonstrations`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from cpp_mujoco.agent.demonstrations import record_demonstrations
from cpp_mujoco.agent.map_pool import MapPool, pad_layout, padded_cell
from cpp_mujoco.agent.replay import ReplayBuffer
from cpp_mujoco.protocol.evaluate import protocol_budgets


class MultiMapReplay(ReplayBuffer):
    """:class:`ReplayBuffer` whose rows also hold each state's map (``map_index``);
    ``obstacle_input``: its states are rebuilt with the obstacle channel."""

    def __init__(
        self,
        capacity: int,
        num_envs: int,
        pool: MapPool,
        n_step: int,
        gamma: float,
        obstacle_input: bool = False,
    ):
        # not ReplayBuffer.__init__: that stores one map and unpacked (rows, envs, H·W) coverage
        self.pool, self.num_envs = pool, num_envs
        self.obstacle_input = obstacle_input
        self.rows = max(capacity // num_envs, n_step + 2)
        self.capacity = self.rows * num_envs
        self.n_step, self.gamma = n_step, gamma
        self.height = self.width = pool.side
        r, n, nbytes = self.rows, num_envs, (pool.side * pool.side + 7) // 8
        self.map_index = np.zeros((r, n), dtype=np.int32)
        self.coverage = np.zeros((r, n, nbytes), dtype=np.uint8)  # packed bits
        self.position = np.zeros((r, n), dtype=np.int64)  # flat cell, padded layout
        self.budget = np.zeros((r, n), dtype=np.float32)
        self.wind = np.zeros((r, n, 2), dtype=np.float32)
        self.action = np.zeros((r, n), dtype=np.int64)
        self.reward = np.zeros((r, n), dtype=np.float32)
        self.terminated = np.zeros((r, n), dtype=bool)
        self.pos = 0
        self.full = False

    def _store_coverage(self, t: int, obs: dict[str, np.ndarray]) -> None:
        """Row ``t``'s map index and coverage as packed bits of the padded layout."""
        n = self.num_envs
        self.map_index[t] = np.asarray(obs["map_index"]).reshape(n)
        self.coverage[t] = np.packbits(np.asarray(obs["coverage"]).reshape(n, -1) != 0, axis=-1)

    def _state(self, t: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, ...]:
        """As :meth:`ReplayBuffer._state`, each row on its own map (moves home by map index)."""
        index, position = self.map_index[t, e], self.position[t, e]
        grid = self.pool.grids(index, self.coverage[t, e], position, self.obstacle_input)
        home = self.pool.moves_home(index, position)
        return grid, self.budget[t, e][:, None], self.wind[t, e], home

    def _safe(self, t: np.ndarray, e: np.ndarray) -> np.ndarray:
        return self.pool.safe_actions(
            self.map_index[t, e], self.position[t, e], self.budget[t, e], self.wind[t, e]
        )

    ARRAYS = ("map_index", "coverage", "position", "budget", "wind", "action", "reward",
              "terminated")  # fmt: skip

    def state_dict(self) -> dict:
        state = {k: torch.from_numpy(getattr(self, k).copy()) for k in self.ARRAYS}
        return {**state, "pos": self.pos, "full": self.full}

    def load_state_dict(self, state: dict) -> None:
        for name in self.ARRAYS:
            value = state[name].numpy()
            if value.shape != getattr(self, name).shape:
                raise ValueError(
                    f"replay memory {name} {value.shape} != {getattr(self, name).shape}"
                )
        for name in self.ARRAYS:
            getattr(self, name)[:] = state[name].numpy()
        self.pos, self.full = int(state["pos"]), bool(state["full"])


@dataclass
class PooledDemonstrations:
    """A planner's transitions on several pool maps: states once, transitions by index."""

    pool: MapPool
    map_index: np.ndarray  # (S,) states …
    coverage: np.ndarray  # (S, bytes) packed, padded layout
    position: np.ndarray  # (S,) flat padded cell
    budget: np.ndarray  # (S,)
    wind: np.ndarray  # (S, 2)
    action: np.ndarray  # (S,) the action taken in state i (transition i starts there)
    ret: np.ndarray  # (S,) n-step return from state i
    discount: np.ndarray  # (S,) γ^n', 0 after a termination
    next_state: np.ndarray  # (S,) bootstrap state's index (itself where discount is 0)
    landing_ratio: float  # the planner's, mean over the recorded maps
    coverage_ratio: float
    named_share: float = 0.0  # of each minibatch from the pool's named maps (0: uniform)
    obstacle_input: bool = False  # states rebuilt with the obstacle channel (MapPool.grids)

    def __post_init__(self) -> None:
        is_named = np.isin(self.map_index, self.pool.named)
        self._named_rows, self._other_rows = np.flatnonzero(is_named), np.flatnonzero(~is_named)
        if self.named_share and (not self._named_rows.size or not self._other_rows.size):
            raise ValueError(
                "named_share needs demonstrations on named and on generated maps alike"
            )

    def __len__(self) -> int:
        return self.action.size

    def _draw(self, batch_size: int, rng: np.random.Generator) -> np.ndarray:
        """Transition indices: uniform, or ``named_share`` of them (binomially) from the
        named maps' and the rest from the generated maps' transitions."""
        if not self.named_share:
            return rng.integers(len(self), size=batch_size)
        k = int(rng.binomial(batch_size, self.named_share))
        named = self._named_rows[rng.integers(self._named_rows.size, size=k)]
        other = self._other_rows[rng.integers(self._other_rows.size, size=batch_size - k)]
        return np.concatenate([named, other])

    def _states(self, i: np.ndarray) -> tuple[np.ndarray, ...]:
        index, position = self.map_index[i], self.position[i]
        grid = self.pool.grids(index, self.coverage[i], position, self.obstacle_input)
        home = self.pool.moves_home(index, position)
        return grid, self.budget[i][:, None], self.wind[i], home

    def sample(self, batch_size: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Drawn transitions (:meth:`_draw`) in :meth:`ReplayBuffer.transitions`' layout."""
        i = self._draw(batch_size, rng)
        nxt = self.next_state[i]
        return {
            "obs": self._states(i),
            "action": self.action[i],
            "return": self.ret[i],
            "next_obs": self._states(nxt),
            "next_safe": self.pool.safe_actions(
                self.map_index[nxt], self.position[nxt], self.budget[nxt], self.wind[nxt]
            ),
            "discount": self.discount[i],
        }


def record_pool_demonstrations(
    pool: MapPool,
    map_ids: list[int],
    planner,
    n_step: int,
    gamma: float,
    budget_step: int | list[int] = 1,
    named_share: float = 0.0,
    obstacle_input: bool = False,
) -> PooledDemonstrations:
    """``planner`` over every landing cell × every ``budget_step``-th budget (one step for all,
    or one per map) of each map ``map_ids`` of the pool (:func:`record_demonstrations`), kept
    compact; ``named_share``, ``obstacle_input``: see :class:`PooledDemonstrations`."""
    steps = [budget_step] * len(map_ids) if isinstance(budget_step, int) else list(budget_step)
    if len(steps) != len(map_ids):
        raise ValueError(f"{len(steps)} budget steps for {len(map_ids)} maps")
    parts: dict[str, list[np.ndarray]] = {}
    landing, coverage = [], []
    offset = 0
    for m, step in zip(map_ids, steps, strict=True):
        grid_map, config = pool.maps[m], pool.configs[m]
        budgets = protocol_budgets(config, step)
        demo = record_demonstrations(grid_map, config, planner, n_step, gamma, budgets)
        landing.append(demo.landing_ratio)
        coverage.append(demo.coverage_ratio)
        mem, rows, eps = demo.memory, demo.rows, demo.episodes
        ret, steps, alive = mem.n_step_window(rows, eps)
        lookup = np.full((mem.rows, mem.num_envs), -1, dtype=np.int64)
        lookup[rows, eps] = np.arange(rows.size) + offset
        nxt = lookup[(rows + steps) % mem.rows, eps]
        if (nxt[alive] < 0).any():
            raise RuntimeError(f"demonstrations on {grid_map.label}: a bootstrap state is missing")
        h, w = grid_map.shape
        cells = pad_layout(mem.coverage[rows, eps], (h, w), pool.side)
        new = {
            "map_index": np.full(rows.size, m, dtype=np.int32),
            "coverage": np.packbits(cells, axis=-1),
            "position": padded_cell(mem.position[rows, eps], w, pool.side),
            "budget": mem.budget[rows, eps],
            "wind": mem.wind[rows, eps],
            "action": mem.action[rows, eps],
            "ret": ret,
            "discount": np.where(alive, gamma**steps, 0.0).astype(np.float32),
            "next_state": np.where(alive, nxt, np.arange(rows.size) + offset),
        }
        for key, value in new.items():
            parts.setdefault(key, []).append(value)
        offset += rows.size
    arrays = {k: np.concatenate(v) for k, v in parts.items()}
    return PooledDemonstrations(
        pool,
        **arrays,
        landing_ratio=float(np.mean(landing)),
        coverage_ratio=float(np.mean(coverage)),
        named_share=named_share,
        obstacle_input=obstacle_input,
    )
