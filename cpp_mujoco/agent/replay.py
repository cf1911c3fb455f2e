"""Replay memory for one fixed map, laid out as (rows, num_envs) so n-step returns are read at
sampling time.

Row t holds, for each environment, the observation s_t (coverage, position, budget — the map is
fixed and stored once, with its moves home per cell, :func:`~cpp_mujoco.agent.home_input.
home_field`), the action, the reward and whether the step terminated. The environments
auto-reset in the same step (gymnasium ``SAME_STEP``), so when step t did not terminate, row t+1
holds s_{t+1}; a terminated step needs no next state (Y = r). The n-step window starting at row t
stops at the first termination; the newest ``n_step`` rows are not sampled until the rows after
them exist.
"""

from __future__ import annotations

import numpy as np
import torch

from cpp_mujoco.agent.home_input import home_after, home_field
from cpp_mujoco.grid.return_rule import paid_actions


class ReplayBuffer:
    def __init__(
        self, capacity: int, num_envs: int, map_layers: np.ndarray, n_step: int, gamma: float
    ):
        self.num_envs = num_envs
        self.rows = max(capacity // num_envs, n_step + 2)
        self.capacity = self.rows * num_envs
        self.n_step, self.gamma = n_step, gamma
        self.map_layers = np.asarray(map_layers, dtype=np.float32)  # (3, H, W)
        self.home = home_field(self.map_layers)  # (H·W,) moves home from each cell
        self.after = home_after(self.map_layers)  # (H·W, 5) actions home after each action
        h, w = self.map_layers.shape[1:]
        self.height, self.width = h, w
        r, n = self.rows, num_envs
        self.coverage = np.zeros((r, n, h * w), dtype=bool)
        self.position = np.zeros((r, n), dtype=np.int64)
        self.budget = np.zeros((r, n), dtype=np.float32)
        self.wind = np.zeros((r, n, 2), dtype=np.float32)  # the observed steady wind
        self.action = np.zeros((r, n), dtype=np.int64)
        self.reward = np.zeros((r, n), dtype=np.float32)
        self.terminated = np.zeros((r, n), dtype=bool)
        self.pos = 0  # next row to write
        self.full = False

    def __len__(self) -> int:
        return (self.rows if self.full else self.pos) * self.num_envs

    def add(self, obs: dict[str, np.ndarray], action, reward, terminated) -> None:
        """Store one vector step: ``obs`` is the batched observation the actions were taken in."""
        t, n = self.pos, self.num_envs
        self._store_coverage(t, obs)
        self.position[t] = np.asarray(obs["position"]).reshape(n, -1).argmax(1)
        self.budget[t] = np.asarray(obs["budget"]).reshape(n)
        self.wind[t] = np.asarray(obs["wind"]).reshape(n, 2) if "wind" in obs else 0.0
        self.action[t] = action
        self.reward[t] = reward
        self.terminated[t] = terminated
        self.pos = (t + 1) % self.rows
        self.full = self.full or self.pos == 0

    def _store_coverage(self, t: int, obs: dict[str, np.ndarray]) -> None:
        """Row ``t``'s coverage, one bool per cell (subclasses keep it in their own layout)."""
        self.coverage[t] = np.asarray(obs["coverage"]).reshape(self.num_envs, -1).astype(bool)

    def _valid_rows(self) -> int:
        """Number of sampleable rows: all stored rows but the newest n_step."""
        return (self.rows if self.full else self.pos) - self.n_step

    def can_sample(self) -> bool:
        return self._valid_rows() > 0

    def sample(self, batch_size: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """``batch_size`` uniformly drawn n-step transitions (see ``transitions``)."""
        valid = self._valid_rows()
        if valid <= 0:
            raise RuntimeError("not enough transitions in the replay buffer to sample")
        oldest = self.pos if self.full else 0
        t = (oldest + rng.integers(valid, size=batch_size)) % self.rows
        e = rng.integers(self.num_envs, size=batch_size)
        return self.transitions(t, e)

    def n_step_window(self, t: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, ...]:
        """Rows ``t`` of envs ``e`` → (R = Σ γ^k r_{t+k}, steps n', alive): the window ends
        after n_step rows or at the first termination (then not ``alive``)."""
        batch_size = t.size
        ret = np.zeros(batch_size, dtype=np.float32)
        alive = np.ones(batch_size, dtype=bool)  # window not yet ended by a termination
        steps = np.zeros(batch_size, dtype=np.int64)
        for k in range(self.n_step):
            row = (t + k) % self.rows
            ret += alive * (self.gamma**k) * self.reward[row, e]
            steps += alive
            alive &= ~self.terminated[row, e]
        return ret, steps, alive

    def transitions(self, t: np.ndarray, e: np.ndarray) -> dict[str, np.ndarray]:
        """Rows ``t`` of envs ``e`` → n-step transitions: s, a, R = Σ γ^k r_{t+k}, bootstrap
        state s_{t+n'}, discount γ^{n'} (0 if the window ended in a termination)."""
        ret, steps, alive = self.n_step_window(t, e)
        nxt = (t + steps) % self.rows
        return {
            "obs": self._state(t, e),
            "action": self.action[t, e],
            "return": ret,
            "next_obs": self._state(nxt, e),
            "next_safe": self._safe(nxt, e),
            "discount": np.where(alive, self.gamma**steps, 0.0).astype(np.float32),
        }

    def _state(self, t: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, ...]:
        """(grid (b,5,H,W), budget (b,1), wind (b,2), moves home (b,)) of rows ``t`` of envs
        ``e``: what :func:`~cpp_mujoco.agent.network.scalar_inputs` reads besides the grid."""
        b = t.size
        hw = self.height * self.width
        grid = np.empty((b, 5, self.height, self.width), dtype=np.float32)
        grid[:, :3] = self.map_layers
        grid[:, 3] = self.coverage[t, e].reshape(b, self.height, self.width)
        pos = np.zeros((b, hw), dtype=np.float32)
        pos[np.arange(b), self.position[t, e]] = 1.0
        grid[:, 4] = pos.reshape(b, self.height, self.width)
        home = self.home[self.position[t, e]]
        return grid, self.budget[t, e][:, None], self.wind[t, e], home

    def _safe(self, t: np.ndarray, e: np.ndarray) -> np.ndarray:
        """(b, 5) bool: the return rule's actions (:func:`~cpp_mujoco.agent.home_input.
        safe_actions`) in rows ``t`` of envs ``e``, for a masked target's bootstrap states (the
        per-map agent masks in calm air only: :class:`~cpp_mujoco.agent.config.TrainConfig`)."""
        return paid_actions(self.after[self.position[t, e]], self.budget[t, e], self.wind[t, e])

    # ------------------------------------------------------------------ checkpointing
    def state_dict(self) -> dict:
        return {
            "coverage": torch.from_numpy(np.packbits(self.coverage, axis=-1)),
            "position": torch.from_numpy(self.position),
            "budget": torch.from_numpy(self.budget),
            "wind": torch.from_numpy(self.wind),
            "action": torch.from_numpy(self.action),
            "reward": torch.from_numpy(self.reward),
            "terminated": torch.from_numpy(self.terminated),
            "pos": self.pos,
            "full": self.full,
        }

    def load_state_dict(self, state: dict) -> None:
        hw = self.height * self.width
        cov = np.unpackbits(state["coverage"].numpy(), axis=-1, count=hw).astype(bool)
        if cov.shape != self.coverage.shape:
            raise ValueError(f"replay buffer shape {cov.shape} != {self.coverage.shape}")
        self.coverage[:] = cov
        for name in ("position", "budget", "action", "reward", "terminated"):
            getattr(self, name)[:] = state[name].numpy()
        # a checkpoint from before the wind option held calm-air observations only
        self.wind[:] = state["wind"].numpy() if "wind" in state else 0.0
        self.pos, self.full = int(state["pos"]), bool(state["full"])


def concatenate_batches(a: dict, b: dict) -> dict:
    """Two sampled batches as one, field by field (``obs``/``next_obs`` are tuples of arrays)."""
    out = {}
    for k, v in a.items():
        if isinstance(v, tuple):
            out[k] = tuple(np.concatenate([x, y]) for x, y in zip(v, b[k], strict=True))
        else:
            out[k] = np.concatenate([v, b[k]])
    return out
