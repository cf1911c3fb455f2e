"""A trained agent as a policy: greedy π(s) = argmax_a Q(s, a), for one observation or a batch."""

from __future__ import annotations

import numpy as np
import torch

from cpp_mujoco.agent.network import QNetwork, observation_to_tensors


class MapSizeError(ValueError):
    """The observation's map size differs from the size the network was built for."""


class GreedyAgent:
    """``act(obs)``: one observation dict (``coverage`` of shape (H, W)) → int; a batch (leading
    dim N) → np.ndarray of N ints. ``network`` is the torch Q-network."""

    def __init__(
        self,
        network: QNetwork,
        budget_scale: float,
        device: str | torch.device = "cpu",
        name: str = "ddqn",
        metadata: dict | None = None,
    ):
        self.network = network.to(device).eval()
        self.budget_scale = float(budget_scale)
        self.device = torch.device(device)
        self.name = name
        self.metadata = dict(metadata or {})

    @property
    def map_shape(self) -> tuple[int, int]:
        return self.network.height, self.network.width

    @torch.no_grad()
    def q_values(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Q-values (N, 5) for a batch of observations."""
        shape = tuple(np.shape(obs["coverage"])[-2:])
        if shape != self.map_shape:
            raise MapSizeError(
                f"agent {self.name!r} was trained on {self.map_shape[0]}x{self.map_shape[1]} maps, "
                f"the observation is {shape[0]}x{shape[1]}"
            )
        grid, budget = observation_to_tensors(obs, self.budget_scale, self.device)
        return self.network(grid, budget).cpu().numpy()

    def act(self, obs: dict[str, np.ndarray]):
        single = np.ndim(obs["coverage"]) == 2
        if single:
            obs = {k: np.asarray(v)[None] for k, v in obs.items()}
        actions = self.q_values(obs).argmax(axis=1)
        return int(actions[0]) if single else actions

    __call__ = act
