"""``cpp_mujoco/Grid-v0``: one grid MDP as a gymnasium env (a batch of one :class:`GridMDP`)."""

from __future__ import annotations

import os
from typing import Any

import gymnasium as gym
import numpy as np

from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.grid.spaces import action_space, observation_space
from cpp_mujoco.maps import GridMap, load_map


class GridEnv(gym.Env):
    """The paper's coverage MDP. ``map`` is a bundled name, a PNG path or a :class:`GridMap`;
    any :class:`GridConfig` field may be passed as a keyword (``fov_side=5``, ``max_budget=100``).

    ``reset(options={"start": (row, col), "budget": int})`` fixes the start cell and/or budget.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(
        self,
        map: str | os.PathLike | GridMap = "A",  # noqa: A002 - the design's keyword
        config: GridConfig | None = None,
        render_mode: str | None = None,
        **config_kwargs: Any,
    ):
        self.grid_map = load_map(map)
        self.config = GridConfig.from_kwargs(config, **config_kwargs)
        self.mdp = GridMDP(self.grid_map, 1, self.config)
        self.observation_space = observation_space(*self.grid_map.shape)
        self.action_space = action_space()
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}")
        self.render_mode = render_mode
        self._needs_reset = True
        self._active = np.ones(1, dtype=bool)  # step() only runs on a live episode

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self.mdp.reset_with_options(self.np_random, options)  # validates and draws
        self._needs_reset = False
        return self._observation(), self._info()

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError("episode is over (or never started): call reset() first")
        out = self.mdp.step(np.array([action], dtype=np.int64), active=self._active)
        terminated = bool(out.terminated[0])
        self._needs_reset = terminated
        return self._observation(), float(out.reward[0]), terminated, False, self._info()

    def _observation(self) -> dict[str, np.ndarray]:
        return self.mdp.observation_of(0)

    def _info(self) -> dict[str, Any]:
        return self.mdp.info_of(0)

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        from cpp_mujoco.review.grid_image import grid_image

        return grid_image(self.grid_map, self.mdp.coverage[0], self.mdp.position[0])
