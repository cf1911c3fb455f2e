"""Simulating ahead from an observation: read the MDP state back out of a batched observation,
and play a policy from such states to the end in a scratch :class:`GridMDP`."""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.maps import GridMap
from cpp_mujoco.protocol.episode import run_batch


def decode_observation(obs: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(flat position (N,), remaining budget (N,), coverage (N, H·W) bool) of a batch."""
    position = np.asarray(obs["position"])
    n = position.shape[0]
    pos = position.reshape(n, -1).argmax(axis=1)
    budget = np.asarray(obs["budget"]).reshape(n).astype(np.int64)
    coverage = np.asarray(obs["coverage"]).reshape(n, -1).astype(bool)
    return pos, budget, coverage


def rollout(
    grid_map: GridMap,
    policy,
    pos: np.ndarray,
    budget: np.ndarray,
    coverage: np.ndarray,
    config: GridConfig | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Play ``policy`` from the given states to the end (an episode start for the policy: a
    planner used as the incumbent starts afresh each time).

    Returns (actions (k, T) padded with LAND, target cells seen at the end (k,), actions taken
    (k,)).
    """
    mdp = GridMDP(grid_map, pos.size, config)
    mdp.restore(pos, budget, coverage)
    taken: list[np.ndarray] = []
    run_batch(mdp, policy, on_step=lambda obs, actions, out, active: taken.append(actions))
    actions = np.stack(taken, axis=1) if taken else np.full((pos.size, 1), LAND)
    return actions, mdp.seen_targets.copy(), mdp.steps.copy()
