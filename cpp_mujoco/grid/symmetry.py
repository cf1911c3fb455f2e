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


# a map shared by the batch: (3, H, W), and its obstacle layer (H, W)
_SHARED_DIMS = {"map": 3, "obstacle": 2}


def _broadcast(value: np.ndarray, key: str) -> bool:
    """A batch's layer that is one map's, broadcast over the rows (stride 0)."""
    return np.ndim(value) == _SHARED_DIMS.get(key, -1) + 1 and value.strides[0] == 0


def turn_observation(obs: dict[str, np.ndarray], symmetry: Symmetry) -> dict[str, np.ndarray]:
    """A batched observation (``map`` (3,H,W) or (N,3,H,W), ``coverage`` and ``position``
    (N,H,W), ``wind`` (N,2)) as seen on the image; other keys (the budget) are unchanged. A map
    broadcast over the batch stays one map, broadcast."""
    out = dict(obs)
    for key in ("map", "coverage", "position", "obstacle"):
        if key not in obs:
            continue
        value = np.asarray(obs[key])
        if _broadcast(value, key):
            one = np.ascontiguousarray(turn_cells(value[0], symmetry))
            out[key] = np.broadcast_to(one, (value.shape[0], *one.shape))
        else:
            out[key] = np.ascontiguousarray(turn_cells(value, symmetry))
    if "wind" in obs:
        out["wind"] = turn_wind(obs["wind"], symmetry)
    return out


def shares_one_map(obs: dict[str, np.ndarray]) -> bool:
    """Every row of the batch is on one map: its layers whole ((3,H,W)) or broadcast."""
    return all(
        np.ndim(obs[key]) == dims or _broadcast(np.asarray(obs[key]), key)
        for key, dims in _SHARED_DIMS.items()
        if key in obs
    )


def stacked_images(
    obs: dict[str, np.ndarray], group: tuple[Symmetry, ...]
) -> dict[str, np.ndarray]:
    """The batch's observation on every image of ``group``, stacked: (len(group) · N, …), image
    by image (a map shared by the batch is repeated for each row)."""
    n = int(np.shape(obs["coverage"])[0])
    images = [turn_observation(obs, symmetry) for symmetry in group]
    out = {}
    for key, value in obs.items():
        parts = [np.asarray(image[key]) for image in images]
        if np.ndim(value) == _SHARED_DIMS.get(key):
            parts = [np.broadcast_to(part, (n, *part.shape)) for part in parts]
        out[key] = np.concatenate(parts)
    return out


def symmetric_q_values(q_values, obs: dict[str, np.ndarray]) -> np.ndarray:
    """The mean over the map's symmetries of ``q_values`` read on each image, each image's
    actions mapped back to the map's. ``q_values`` reads a batch of observations → (M, 5). A
    batch of several rows on one map reads each image apart (M = N): an image's rows share its
    map, so rows of the same grid are read once (the agent's shared features; a batch's
    episodes often fly the same first steps); otherwise — one UAV — once, on the images stacked
    (:func:`stacked_images`: M = 8 N for a square map), its eight readings one forward pass. A
    row's Q-values do not depend on its batch, so both give the same numbers."""
    n = int(np.shape(obs["coverage"])[0])
    group = symmetries_of(tuple(np.shape(obs["coverage"])[-2:]))
    if n >= 2 and shares_one_map(obs):
        q = np.stack([np.asarray(q_values(turn_observation(obs, s))) for s in group])
    else:
        q = np.asarray(q_values(stacked_images(obs, group))).reshape(len(group), n, -1)
    total = q[0][:, PERMUTATIONS[group[0]]]
    for image, symmetry in zip(q[1:], group[1:], strict=True):
        total = total + image[:, PERMUTATIONS[symmetry]]
    return total / len(group)
