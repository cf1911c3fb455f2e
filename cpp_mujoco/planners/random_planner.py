"""The floor of every comparison: uniformly random actions."""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.actions import NUM_ACTIONS


class RandomPlanner:
    """Uniform random actions from a stream seeded by ``seed``.

    Every episode start reseeds the stream from (``seed``, the start's seed), so a protocol run
    twice — or its episodes spread over worker processes in any order — gives the same results.
    """

    name = "random"

    def __init__(self, seed: int = 0):
        self.seed = int(seed)
        self.rng = np.random.default_rng(self.seed)

    def reset(self, num_episodes: int, seed: int | None = None) -> None:
        entropy = [self.seed] if seed is None else [self.seed, int(seed)]
        self.rng = np.random.default_rng(entropy)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return self.rng.integers(NUM_ACTIONS, size=np.asarray(obs["budget"]).shape[0])
