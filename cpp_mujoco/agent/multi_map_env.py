"""Training episodes on many maps at once: each of N slots flies its own map of a pool.

Each slot is a one-environment :class:`GridMDP` of its map, so slots on maps of different sizes
step side by side (measured: 45–50 µs a step per slot, 0.2–0.5 ms to build a slot's MDP, against
30+ ms for a training update). Every ``episodes_per_map`` episodes (default 1: every reset) a slot
draws a new map from the pool — with one map per episode the replay memory holds as many maps as
it holds episodes, so a minibatch never overfits the few maps the slots happen to be on, and the
cost is one MDP built per episode.

Observations are those of the grid env padded to the pool's side (:class:`MapPool`): ``map`` is
no-fly outside the map, coverage and position are zero there; ``map_index`` says which pool map a
row is on. A pool with obstacles adds each row's ``obstacle`` layer (zeros on its maps without
obstacles and on the padding), whatever network trains on it: as the grid env does on a map with
obstacles, so the guide planner sees what the camera sees and the keys never change mid-run
(a network without the obstacle input cannot fly such a pool; the config refuses that).

Resets happen in the step that ended the episode (gymnasium's ``SAME_STEP``), with
``info["final_info"]`` holding the ended episodes' ``landed`` and ``coverage_ratio``, as the
per-map :class:`~cpp_mujoco.agent.train.Trainer`'s collection reads them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cpp_mujoco.agent.map_pool import MapPool, pad_layout
from cpp_mujoco.grid.mdp import GridMDP


class MultiMapVectorEnv:
    """``named_share``: the fraction of map draws that pick one of the pool's named maps
    (:attr:`MapPool.named`, uniformly), the rest a generated one — a few maps a user brings
    would otherwise be drawn once in a thousand episodes."""

    def __init__(
        self, pool: MapPool, num_envs: int, episodes_per_map: int = 1, named_share: float = 0.0
    ):
        if num_envs < 1 or episodes_per_map < 1:
            raise ValueError("num_envs and episodes_per_map must be >= 1")
        if not 0.0 <= named_share < 1.0:
            raise ValueError(f"named_share must lie in [0, 1), got {named_share}")
        self.pool, self.num_envs, self.episodes_per_map = pool, num_envs, episodes_per_map
        named = pool.named
        self.named_share = named_share if named.size else 0.0
        self._named = named
        self._generated = np.setdiff1d(np.arange(len(pool)), named)
        self.rng = np.random.default_rng()
        self.map_index = np.zeros(num_envs, dtype=np.int64)
        self.episodes_on_map = np.zeros(num_envs, dtype=np.int64)
        self.mdps = [self._mdp(0) for _ in range(num_envs)]

    @property
    def unwrapped(self) -> MultiMapVectorEnv:
        """As a gymnasium env's: the checkpoint code reads the state through it."""
        return self

    def _mdp(self, m: int) -> GridMDP:
        return GridMDP(self.pool.maps[m], 1, self.pool.configs[m])

    def _start_episode(self, i: int) -> None:
        """Slot ``i``'s next episode; on a new map after ``episodes_per_map`` of them."""
        if self.episodes_on_map[i] >= self.episodes_per_map:
            self.map_index[i] = self._draw_map()
            self.mdps[i] = self._mdp(int(self.map_index[i]))
            self.episodes_on_map[i] = 0
        self.mdps[i].reset(self.rng)
        self.episodes_on_map[i] += 1

    def _draw_map(self) -> int:
        if not self.named_share:  # without named maps: the draw of runs from before them
            return int(self.rng.integers(len(self.pool)))
        if self.rng.random() < self.named_share:
            return int(self.rng.choice(self._named))
        return int(self.rng.choice(self._generated))

    def reset(self, *, seed: int | None = None) -> tuple[dict[str, np.ndarray], dict]:
        self.rng = np.random.default_rng(seed)
        self.episodes_on_map[:] = self.episodes_per_map  # every slot draws a map
        for i in range(self.num_envs):
            self._start_episode(i)
        return self.observation(), {}

    def step(self, actions) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray, dict]:
        actions = np.asarray(actions, dtype=np.int64).reshape(self.num_envs)
        reward = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        for i, mdp in enumerate(self.mdps):
            out = mdp.step(actions[i : i + 1])
            reward[i], terminated[i] = out.reward[0], out.terminated[0]
        info: dict[str, Any] = {}
        if terminated.any():
            landed = np.zeros(self.num_envs, dtype=bool)
            coverage = np.zeros(self.num_envs)
            for i in np.flatnonzero(terminated):
                mdp = self.mdps[i]
                landed[i], coverage[i] = mdp.landed[0], mdp.seen_targets[0] / mdp.num_targets
                self._start_episode(int(i))
            info = {
                "final_info": {"landed": landed, "coverage_ratio": coverage},
                "_final_info": terminated.copy(),
            }
        truncated = np.zeros(self.num_envs, dtype=bool)
        return self.observation(), reward, terminated, truncated, info

    def observation(self) -> dict[str, np.ndarray]:
        """The grid env's batched observation, padded to the pool's side, plus ``map_index``."""
        n, side = self.num_envs, self.pool.side
        coverage = np.zeros((n, side, side), dtype=np.int8)
        position = np.zeros((n, side, side), dtype=np.int8)
        budget = np.zeros((n, 1), dtype=np.float32)
        safety = np.zeros((n, 1), dtype=np.int8)
        wind = np.zeros((n, 2), dtype=np.float32)
        for i, mdp in enumerate(self.mdps):
            h, w = mdp.height, mdp.width
            coverage[i, :h, :w] = mdp.coverage[0].reshape(h, w)
            position[i, mdp.position[0] // w, mdp.position[0] % w] = 1
            budget[i] = np.floor(mdp.budget[0])
            safety[i] = mdp.rejected[0]
            wind[i] = mdp.winds.vector[0]
        obs = {
            "map": self.pool.layers[self.map_index],
            "coverage": coverage,
            "position": position,
            "budget": budget,
            "safety": safety,
            "wind": wind,
            "map_index": self.map_index.copy(),
        }
        if self.pool.has_obstacles:
            obs["obstacle"] = self.pool.obstacles[self.map_index]
        return obs

    # ------------------------------------------------------------------ saving and restoring
    def state_dict(self) -> dict[str, Any]:
        """Flat arrays (a checkpoint stores them as tensors): each slot's MDP state arrays side
        by side, coverage in the padded layout, the slots' maps and the generator state."""
        side = self.pool.side
        per_slot = [mdp.state_dict() for mdp in self.mdps]
        state: dict[str, Any] = {}
        for key in per_slot[0]:
            if key == "coverage":
                shapes = [mdp.map.shape for mdp in self.mdps]
                parts = [
                    pad_layout(s[key], hw, side) for s, hw in zip(per_slot, shapes, strict=True)
                ]
            else:
                parts = [s[key] for s in per_slot]
            state[key] = np.concatenate(parts)
        state.update(
            map_index=self.map_index.copy(),
            episodes_on_map=self.episodes_on_map.copy(),
            rng=self.rng.bit_generator.state,
        )
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """The inverse of :meth:`state_dict`; ``ValueError`` when it does not fit this pool
        and slot count (nothing changes then)."""
        state = dict(state)
        try:
            index = np.asarray(state.pop("map_index"), dtype=np.int64)
            episodes = np.asarray(state.pop("episodes_on_map"), dtype=np.int64)
            rng_state = state.pop("rng")
        except KeyError as exc:
            raise ValueError(f"env state lacks {exc}") from None
        if index.shape != (self.num_envs,) or not ((index >= 0) & (index < len(self.pool))).all():
            raise ValueError(f"env state's map_index does not fit {self.num_envs} slots and "
                             f"a pool of {len(self.pool)} maps")  # fmt: skip
        mdps = [self._mdp(int(m)) for m in index]
        for i, mdp in enumerate(mdps):
            own = {k: np.asarray(v)[i : i + 1] for k, v in state.items()}
            if "coverage" in own:
                h, w = mdp.map.shape
                side = self.pool.side
                own["coverage"] = own["coverage"].reshape(1, side, side)[:, :h, :w].reshape(1, -1)
            mdp.load_state_dict(own)
        rng = np.random.default_rng()
        try:
            rng.bit_generator.state = rng_state
        except (TypeError, ValueError, KeyError) as exc:
            raise ValueError(f"env state 'rng' is not a generator state ({exc})") from None
        self.mdps, self.map_index, self.episodes_on_map, self.rng = mdps, index, episodes, rng
