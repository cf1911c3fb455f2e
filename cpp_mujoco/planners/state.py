"""Reading the MDP state back out of a batched observation."""

from __future__ import annotations

import numpy as np


def decode_observation(obs: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(flat position (N,), remaining budget (N,), coverage (N, H·W) bool) of a batch."""
    position = np.asarray(obs["position"])
    n = position.shape[0]
    pos = position.reshape(n, -1).argmax(axis=1)
    budget = np.asarray(obs["budget"]).reshape(n).astype(np.int64)
    coverage = np.asarray(obs["coverage"]).reshape(n, -1).astype(bool)
    return pos, budget, coverage
