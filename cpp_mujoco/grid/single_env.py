"""What ``Grid-v0`` and ``MuJoCo-v0`` share: one env over a batch-of-one :class:`GridMDP`.

Reset with options, the needs-reset guard, the action check, the spaces and the observation and
info views are written here once, so the two backends cannot drift apart in what they accept or
report. A backend only says how an action becomes a :class:`~cpp_mujoco.grid.mdp.StepOutcome`
(:meth:`SingleGridEnv._transition`); both end in :meth:`GridMDP.apply`, the one place where
reward, crash and termination are decided.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from cpp_mujoco.grid.mdp import GridConfig, GridMDP, StepOutcome
from cpp_mujoco.grid.spaces import (
    RENDER_MODES,
    action_space,
    check_action,
    check_render_mode,
    observation_space,
    reset_options,
)
from cpp_mujoco.maps import GridMap


class SingleGridEnv(gym.Env):
    """Base of the single envs; ``reset(options={"start": (row, col), "budget": int})``."""

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 4}

    def __init__(self, grid_map: GridMap, config: GridConfig, render_mode: str | None = None):
        self.render_mode = check_render_mode(render_mode)
        self.grid_map = grid_map
        self.mdp = GridMDP(grid_map, 1, config)
        self.observation_space = observation_space(*grid_map.shape, grid_map.has_obstacles)
        self.action_space = action_space()
        self._needs_reset = True

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        start, budget, _ = reset_options(options)
        self.mdp.reset(self.np_random, start=start, budget=budget)  # validates, then draws
        self._needs_reset = True  # until the backend's own reset has succeeded too
        self._on_reset()
        self._needs_reset = False
        return self._observation(), self._info()

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError("episode is over (or never started): call reset() first")
        action = check_action(action)  # before the state changes: a bad action changes nothing
        out = self._transition(action)
        terminated = bool(out.terminated[0])
        self._needs_reset = terminated
        return self._observation(), float(out.reward[0]), terminated, False, self._info()

    # ------------------------------------------------------------------ what a backend adds
    def _transition(self, action: int) -> StepOutcome:
        """Carry out one checked action on the live episode; end in ``self.mdp.apply``."""
        raise NotImplementedError

    def _on_reset(self) -> None:
        """Backend state to reset after the MDP drew its start and budget."""

    def _observation(self) -> dict[str, np.ndarray]:
        return self.mdp.observation_of(0)

    def _info(self) -> dict[str, Any]:
        return self.mdp.info_of(0)
