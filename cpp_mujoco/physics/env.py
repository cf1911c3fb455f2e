"""``cpp_mujoco/MuJoCo-v0``: the grid MDP's actions flown by a MuJoCo quadrotor.

Same spaces, reset options and info keys as ``cpp_mujoco/Grid-v0``, so a grid agent runs
unchanged. What changes is where the numbers come from: the safety controller still decides each
action (the very same :class:`SafetyController`), but the move is flown, coverage is what the
camera footprint saw, and the budget is the battery's remaining energy in calibrated units.

The grid-level state (cell, coverage, budget, flags) lives in a one-env :class:`GridMDP` so that
reset draws and observations are exactly the grid env's; this env writes the physical outcome
into it instead of calling its ``step``.
"""

from __future__ import annotations

import math
import os
from dataclasses import fields
from typing import Any

import gymnasium as gym
import numpy as np

from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.grid.spaces import action_space, observation_space
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.calibration import unit_energy
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.flight import ActionResult, Flight

BUDGET_EXHAUSTED = "budget exhausted before landing"


def split_kwargs(kwargs: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Route ``gymnasium.make`` keywords to :class:`PhysicsConfig` or :class:`GridConfig`."""
    physics, grid = PhysicsConfig.field_names(), {f.name for f in fields(GridConfig)}
    unknown = set(kwargs) - physics - grid
    if unknown:
        raise TypeError(
            f"unknown option(s) {sorted(unknown)}; physics: {sorted(physics)}; grid: {sorted(grid)}"
        )
    return (
        {k: v for k, v in kwargs.items() if k in physics},
        {k: v for k, v in kwargs.items() if k in grid},
    )


class MuJoCoEnv(gym.Env):
    """The coverage MDP in physics. ``map`` is a bundled name, a PNG path or a :class:`GridMap`;
    keywords set :class:`PhysicsConfig` fields (``wind_speed=5``) or :class:`GridConfig` fields
    (``max_budget=50``). ``reset(options={"start": (row, col), "budget": int})`` as the grid env.

    ``model`` and ``data`` are the MuJoCo ``MjModel`` / ``MjData``.
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        map: str | os.PathLike | GridMap = "A",  # noqa: A002 - the design's keyword
        config: PhysicsConfig | None = None,
        grid_config: GridConfig | None = None,
        render_mode: str | None = None,
        **kwargs: Any,
    ):
        if render_mode is not None:
            raise ValueError("MuJoCo-v0 has no render modes yet")
        physics_kw, grid_kw = split_kwargs(kwargs)
        base = config or PhysicsConfig()
        self.config = PhysicsConfig(
            **{**{f: getattr(base, f) for f in base.field_names()}, **physics_kw}
        )
        self.grid_config = GridConfig.from_kwargs(grid_config, **grid_kw)
        self.grid_map = load_map(map)
        self.mdp = GridMDP(self.grid_map, 1, self.grid_config)
        self.arena = build_arena(self.grid_map, self.config, self.grid_config.fov_side)
        self.model = compile_arena(self.arena)
        self.flight = Flight(self.model, self.grid_map, self.config, coverage=self.mdp.coverage)
        self.data = self.flight.data
        self.unit_energy = unit_energy(self.config)
        self.observation_space = observation_space(*self.grid_map.shape)
        self.action_space = action_space()
        self.render_mode = None
        self._needs_reset = True
        self._last = ActionResult()
        self._crash_reason: str | None = None

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self.mdp.reset_with_options(self.np_random, options)  # validates and draws
        row, col = divmod(int(self.mdp.position[0]), self.mdp.width)
        capacity = float(self.mdp.budget[0]) * self.unit_energy
        self.flight.reset(row, col, capacity, rng=self.np_random)
        self._last = ActionResult()
        self._crash_reason = None
        self._needs_reset = False
        return self._observation(), self._info()

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError("episode is over (or never started): call reset() first")
        if not self.action_space.contains(action):
            raise ValueError(f"action must be in 0..{self.action_space.n - 1}, got {action!r}")
        m = self.mdp
        cell = int(m.position[0])
        next_cell, rejected, lands = m.safety.decide(cell, int(action))
        next_cell, rejected, lands = int(next_cell), bool(rejected), bool(lands)
        if lands:
            result = self.flight.land(cell)
        elif rejected:
            result = self.flight.hover(cell)
        else:
            result = self.flight.move(next_cell)
        self._last = result

        remaining = max(self.flight.capacity - self.flight.energy_used, 0.0)
        budget = math.floor(remaining / self.unit_energy + 1e-9)
        landed = result.landed
        crashed = result.failure is not None or (budget == 0 and not landed)
        self._crash_reason = result.failure or (BUDGET_EXHAUSTED if crashed else None)
        m.position[0] = next_cell
        m.budget[0] = budget
        m.rejected[0] = rejected  # the safety flag of the observation
        m.landed[0] = landed
        m.crashed[0] = crashed
        m.seen_targets[0] += result.newly_seen
        reward = float(
            self.grid_config.rewards(
                np.array(result.newly_seen), np.array(rejected), np.array(crashed)
            )
        )
        terminated = landed or crashed or budget == 0
        self._needs_reset = terminated
        return self._observation(), reward, terminated, False, self._info()

    # ------------------------------------------------------------------ views
    def _observation(self) -> dict[str, np.ndarray]:
        return self.mdp.observation_of(0)

    def _info(self) -> dict[str, Any]:
        f = self.flight
        return {
            **self.mdp.info_of(0),
            "energy_used_j": float(f.energy_used),
            "flight_time_s": float(f.time),
            "nfz_violations": int(f.nfz_violations),
            "tracking_error_m": float(self._last.tracking_error),
            "crash_reason": self._crash_reason,
        }
