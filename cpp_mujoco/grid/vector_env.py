"""The native batched env: ``gymnasium.make_vec("cpp_mujoco/Grid-v0", num_envs=N, map=...)``.

All N environments live in one :class:`GridMDP`; a step is a handful of array operations, not N
Python calls. Gymnasium's vector API: infos are dicts of arrays with ``_key`` masks.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from gymnasium.spaces import MultiDiscrete
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.grid.safety import NUM_ACTIONS
from cpp_mujoco.grid.spaces import action_space, observation_space
from cpp_mujoco.maps import GridMap, load_map


class GridVectorEnv(VectorEnv):
    """N grid MDPs stepped together.

    ``autoreset_mode``: ``NEXT_STEP`` (gymnasium's default: the step after an episode ends resets
    that env and ignores its action), ``SAME_STEP`` (reset at once; the last observation of the
    ended episode is in ``info["final_obs"]``, its info in ``info["final_info"]``) or
    ``DISABLED`` (call ``reset(options={"reset_mask": mask})`` yourself).
    """

    def __init__(
        self,
        num_envs: int = 1,
        map: str | os.PathLike | GridMap = "A",  # noqa: A002 - the design's keyword
        config: GridConfig | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **config_kwargs: Any,
    ):
        self.grid_map = load_map(map)
        self.config = GridConfig.from_kwargs(config, **config_kwargs)
        self.num_envs = num_envs
        self.mdp = GridMDP(self.grid_map, num_envs, self.config)
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.metadata = {"autoreset_mode": self.autoreset_mode, "render_modes": []}
        self.single_observation_space = observation_space(*self.grid_map.shape)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.single_action_space = action_space()
        self.action_space = MultiDiscrete(np.full(num_envs, NUM_ACTIONS))
        self._pending_reset = np.zeros(num_envs, dtype=bool)
        self._all = np.ones(num_envs, dtype=bool)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if seed is not None:
            self._np_random, self._np_random_seed = seeding.np_random(seed)
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        start, budget = options.pop("start", None), options.pop("budget", None)
        if options:
            raise ValueError(
                f"unknown reset option(s) {sorted(options)}; known: start, budget, reset_mask"
            )
        if mask is not None:
            mask = np.asarray(mask, dtype=bool)
        self.mdp.reset(self.np_random, mask=mask, start=start, budget=budget)
        self._pending_reset[mask if mask is not None else self._all] = False
        return self.mdp.observation(), self._infos()

    def step(self, actions):
        actions = np.asarray(actions, dtype=np.int64).reshape(self.num_envs)
        resetting = self._pending_reset
        out = self.mdp.step(actions, active=~resetting & ~self.mdp.done)
        terminated = out.terminated & ~resetting
        truncated = np.zeros(self.num_envs, dtype=bool)
        if self.autoreset_mode is AutoresetMode.NEXT_STEP:
            if resetting.any():
                self.mdp.reset(self.np_random, mask=resetting)
            self._pending_reset = terminated.copy()
            return self.mdp.observation(), out.reward, terminated, truncated, self._infos()
        if self.autoreset_mode is AutoresetMode.SAME_STEP and terminated.any():
            final_obs, final_info = self.mdp.observation(), self._infos()
            self.mdp.reset(self.np_random, mask=terminated)
            infos = self._infos()
            infos.update(final_obs=final_obs, final_info=final_info, _final_obs=terminated.copy())
            infos["_final_info"] = terminated.copy()
            return self.mdp.observation(), out.reward, terminated, truncated, infos
        return self.mdp.observation(), out.reward, terminated, truncated, self._infos()

    def _infos(self) -> dict[str, np.ndarray]:
        info = self.mdp.info()
        info.update({f"_{k}": self._all for k in list(info)})
        return info
