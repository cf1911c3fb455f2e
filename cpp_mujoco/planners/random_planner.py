"""The floor of every comparison: uniformly random actions."""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.safety import NUM_ACTIONS


class RandomPlanner:
    name = "random"

    def __init__(self, seed: int = 0):
        self.rng = np.random.default_rng(seed)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return self.rng.integers(NUM_ACTIONS, size=np.asarray(obs["budget"]).shape[0])
