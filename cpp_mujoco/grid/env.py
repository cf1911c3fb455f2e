"""``cpp_mujoco/Grid-v0``: one grid MDP as a gymnasium env (a batch of one :class:`GridMDP`)."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from cpp_mujoco.grid.image import grid_image
from cpp_mujoco.grid.mdp import GridConfig, StepOutcome
from cpp_mujoco.grid.single_env import SingleGridEnv
from cpp_mujoco.maps import GridMap, load_map


class GridEnv(SingleGridEnv):
    """The paper's coverage MDP. ``map`` is a bundled name, a PNG path or a :class:`GridMap`;
    any :class:`GridConfig` field may be passed as a keyword (``fov_side=5``, ``max_budget=100``).

    ``reset(options={"start": (row, col), "budget": int})`` fixes the start cell and/or budget.
    """

    def __init__(
        self,
        map: str | os.PathLike | GridMap = "A",  # noqa: A002 - the design's keyword
        config: GridConfig | None = None,
        render_mode: str | None = None,
        **config_kwargs: Any,
    ):
        self.config = GridConfig.from_kwargs(config, **config_kwargs)
        super().__init__(load_map(map), self.config, render_mode)
        self._active = np.ones(1, dtype=bool)  # step() only runs on a live episode

    def _transition(self, action: int) -> StepOutcome:
        return self.mdp.step(np.array([action], dtype=np.int64), active=self._active)

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None

        return grid_image(self.grid_map, self.mdp.coverage[0], self.mdp.position[0])
