"""Q-values of a batch on one map, each distinct grid read by the convolutions once.

Why: the episodes of a protocol share a map, and those from one landing cell differ only in
their budgets, so at a step many rows hold the same grid (coverage and UAV cell) with other
scalars — the value beam's paths at a depth half of the time on 32×32 maps. A general network
reads the grid (its views, convolutions and moves to new targets: three quarters of its time)
apart from the scalars (:meth:`~cpp_mujoco.agent.general_network.GeneralQNetwork.features`),
so each distinct grid is read once and its features handed to every row that holds it.

The numbers stay the same bit for bit: the convolutions give a row the same features in any
batch, and the dense head — whose matrix products round otherwise in batches under 16 rows —
runs on the very chunks of rows the plain pass runs on (tested against it).
"""

from __future__ import annotations

import numpy as np
import torch

from cpp_mujoco.agent.network import observation_scalars, observation_to_tensors
from cpp_mujoco.grid.actions import NUM_ACTIONS
from cpp_mujoco.grid.symmetry import shares_one_map

BLOCK_CHUNKS = 16  # rows are matched within blocks of this many forward chunks (bounds memory)
Observation = dict[str, np.ndarray]


def batch_rows(key: str, value, lo: int, hi: int | None, rows: np.ndarray | None = None):
    """Rows lo:hi (or ``rows``) of a batched observation array; a map shared by the batch
    ((3, H, W), its obstacle layer (H, W), or a broadcast of one) stays shared."""
    value = np.asarray(value)
    if (key == "map" and value.ndim == 3) or (key == "obstacle" and value.ndim == 2):
        return value
    if key in ("map", "obstacle") and value.shape[0] and value.strides[0] == 0:
        count = len(range(value.shape[0])[lo:hi]) if rows is None else len(rows)
        return np.broadcast_to(value[0], (count, *value.shape[1:]))
    return value[rows] if rows is not None else value[lo:hi]


@torch.no_grad()
def shared_q_values(agent, obs: Observation, step: int) -> np.ndarray | None:
    """``agent``'s Q-values (N, 5) of ``obs`` read in forward chunks of ``step`` rows, each
    distinct grid's features computed once; None where they cannot be shared (a network
    without :meth:`features`, rows on several maps, fewer than two rows)."""
    net = agent.network
    n = int(np.shape(obs["coverage"])[0])
    if not hasattr(net, "features") or n < 2 or not shares_one_map(obs):
        return None
    keys = _grid_keys(obs)
    out = np.empty((n, NUM_ACTIONS), dtype=np.float32)
    for block in range(0, n, step * BLOCK_CHUNKS):
        end = min(n, block + step * BLOCK_CHUNKS)
        _, first, inverse = np.unique(keys[block:end], return_index=True, return_inverse=True)
        distinct = block + first
        features = [
            net.features(_grid(agent, obs, distinct[i : i + step]))
            for i in range(0, distinct.size, step)
        ]
        features = features[0] if len(features) == 1 else torch.cat(features)
        inverse = torch.as_tensor(inverse.reshape(-1), device=features.device)
        for lo in range(block, end, step):
            hi = min(lo + step, end)
            part = {k: batch_rows(k, v, lo, hi) for k, v in obs.items()}
            scalars = observation_scalars(
                part, agent.budget_scale, agent.device, net.wind_inputs, net.home_input
            )
            q = net.q_from_features(features[inverse[lo - block : hi - block]], scalars)
            out[lo:hi] = q.cpu().numpy()
    return out


def _grid(agent, obs: Observation, rows: np.ndarray) -> torch.Tensor:
    """The network's grid tensor of ``rows``."""
    part = {k: batch_rows(k, v, 0, None, rows) for k, v in obs.items()}
    net = agent.network
    grid, _ = observation_to_tensors(
        part, agent.budget_scale, agent.device, net.wind_inputs, False, agent.reads_obstacles
    )
    return grid


def _grid_keys(obs: Observation) -> np.ndarray:
    """(N,) one bytes key per row, equal exactly where the rows' coverage and UAV layers are:
    the layers packed to bits where they hold only 0 and 1, else their bytes."""
    n = int(np.shape(obs["coverage"])[0])
    layers = np.concatenate(
        [np.asarray(obs[k]).reshape(n, -1) for k in ("coverage", "position")], axis=1
    )
    if layers.dtype.kind in "biu" and layers.size and 0 <= layers.min() and layers.max() <= 1:
        layers = np.packbits(layers.astype(bool), axis=1)
    layers = np.ascontiguousarray(layers)
    return layers.view(np.dtype((np.void, layers.shape[1] * layers.itemsize))).reshape(n)
