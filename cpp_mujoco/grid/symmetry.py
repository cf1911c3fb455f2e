"""The grid's actions and observations under the map's symmetries (:mod:`cpp_mujoco.maps.symmetry`).

A map turned or mirrored, flown from the turned start with the turned actions, is the same
mission: here are the turned actions and observations, and the Q-values averaged over the images
(``symmetric_q``, :class:`~cpp_mujoco.agent.policy.GreedyAgent`).
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.actions import MOVES
from cpp_mujoco.maps.symmetry import (
    SYMMETRIES,
    Symmetry,
    symmetries_of,
    turn_cells,
    turn_move,
    turn_wind,
)

# what results record of a policy that averages its Q-values (policy_identity); a changed rule
# gets a new name here
SYMMETRIC_Q_RULE = (
    "d4-mean-v1 (Q-values averaged over the map's rotations and mirror images: 8 for a square "
    "map, 4 otherwise)"
)


def action_permutation(symmetry: Symmetry) -> np.ndarray:
    """(5,) int: ``perm[a]`` is the image's action for action ``a`` (landing stays landing)."""
    index = {tuple(m): i for i, m in enumerate(MOVES.tolist())}
    return np.array([index[turn_move(r, c, symmetry)] for r, c in MOVES.tolist()])


PERMUTATIONS = {s: action_permutation(s) for s in SYMMETRIES}  # read per step: computed once


def turn_observation(obs: dict[str, np.ndarray], symmetry: Symmetry) -> dict[str, np.ndarray]:
    """A batched observation (``map`` (3,H,W) or (N,3,H,W), ``coverage`` and ``position``
    (N,H,W), ``wind`` (N,2)) as seen on the image; other keys (the budget) are unchanged."""
    out = dict(obs)
    for key in ("map", "coverage", "position", "obstacle"):
        if key in obs:
            out[key] = np.ascontiguousarray(turn_cells(obs[key], symmetry))
    if "wind" in obs:
        out["wind"] = turn_wind(obs["wind"], symmetry)
    return out


def symmetric_q_values(q_values, obs: dict[str, np.ndarray]) -> np.ndarray:
    """The mean over the map's symmetries of ``q_values`` (a batch of observations → (N, 5))
    read on each image, each image's actions mapped back to the map's."""
    shape = tuple(np.shape(obs["coverage"])[-2:])
    group = symmetries_of(shape)
    total = None
    for symmetry in group:
        q = np.asarray(q_values(turn_observation(obs, symmetry)))[:, PERMUTATIONS[symmetry]]
        total = q if total is None else total + q
    return total / len(group)
