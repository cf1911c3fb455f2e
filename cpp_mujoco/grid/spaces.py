"""Observation and action spaces, shared by the grid and physics envs so one agent runs on both."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from cpp_mujoco.grid.safety import NUM_ACTIONS

MAX_BUDGET = 100_000  # upper bound of the budget observation; larger budgets are rejected


def observation_space(height: int, width: int) -> spaces.Dict:
    """``map`` (3,H,W) [landing, target, no-fly], ``coverage`` (H,W), ``position`` (H,W) one-hot,
    ``budget`` (1,) remaining movement budget, ``safety`` (1,) last action rejected."""
    return spaces.Dict(
        {
            "map": spaces.MultiBinary((3, height, width)),
            "coverage": spaces.MultiBinary((height, width)),
            "position": spaces.MultiBinary((height, width)),
            "budget": spaces.Box(0.0, float(MAX_BUDGET), shape=(1,), dtype=np.float32),
            "safety": spaces.MultiBinary(1),
        }
    )


def action_space() -> spaces.Discrete:
    """0 north, 1 east, 2 south, 3 west, 4 land."""
    return spaces.Discrete(NUM_ACTIONS)
