"""``cpp_mujoco/MuJoCo-v0``: the grid MDP's actions flown by a MuJoCo quadrotor.

Same spaces, reset options and info keys as ``cpp_mujoco/Grid-v0`` (both derive from
:class:`~cpp_mujoco.grid.single_env.SingleGridEnv`), so a grid agent runs unchanged. What changes
is where the outcome of an action comes from: the safety controller still decides it (the very
same :class:`SafetyController`), but the move is flown, coverage is what the camera footprint
saw, and the budget is the LiPo pack's remaining drawable energy in calibrated units (a calm
move's energy drawn from the pack, I²R loss included; ``info`` adds ``state_of_charge`` and
``battery_voltage_v``). That outcome goes
through :meth:`GridMDP.apply`, the grid's own rules for reward, crash and termination.
"""

from __future__ import annotations

import math
import os
import weakref
from dataclasses import fields
from typing import Any

import numpy as np

from cpp_mujoco.grid.mdp import GridConfig, Outcome, StepOutcome
from cpp_mujoco.grid.single_env import SingleGridEnv
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.calibration import unit_energy
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.flight import ActionResult, Flight
from cpp_mujoco.physics.return_guard import ReturnGuard

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


def make_configs(
    config: PhysicsConfig | None, grid_config: GridConfig | None, kwargs: dict[str, Any]
) -> tuple[PhysicsConfig, GridConfig]:
    """The physics and grid configs of a ``MuJoCo-v0`` env (single or batched): the given
    configs with the keywords (:func:`split_kwargs`) on top."""
    physics_kw, grid_kw = split_kwargs(kwargs)
    base = config or PhysicsConfig()
    physics = PhysicsConfig(**{**{f: getattr(base, f) for f in base.field_names()}, **physics_kw})
    grid = GridConfig.from_kwargs(grid_config, **grid_kw)
    if grid.wind is not None:
        raise ValueError(
            "the grid's wind option sets grid costs; in physics the wind is flown: use "
            "wind_speed, wind_direction and turbulence"
        )
    return physics, grid


class MuJoCoEnv(SingleGridEnv):
    """The coverage MDP in physics. ``map`` is a bundled name, a PNG path or a :class:`GridMap`;
    keywords set :class:`PhysicsConfig` fields (``wind_speed=5``; the controller's bandwidths as
    ``controller={"position_bw": 3}``, see :class:`~cpp_mujoco.physics.config.ControllerGains`)
    or :class:`GridConfig` fields (``max_budget=50``).
    ``reset(options={"start": (row, col), "budget": int})`` as the grid env.
    The flight uses the default parts (:mod:`cpp_mujoco.physics.parts`) with these settings: the
    budget unit is calibrated with exactly them.

    ``model`` and ``data`` are the MuJoCo ``MjModel`` / ``MjData``. ``render_mode="rgb_array"``:
    :meth:`render` returns the chase camera's (H, W, 3) frame (offscreen EGL/OSMesa, created on
    the first call so envs that never render never touch GL); ``render_size`` is (width, height).
    """

    def __init__(
        self,
        map: str | os.PathLike | GridMap = "A",  # noqa: A002 - the design's keyword
        config: PhysicsConfig | None = None,
        grid_config: GridConfig | None = None,
        render_mode: str | None = None,
        render_size: tuple[int, int] = (512, 384),  # multiples of 16 for video codecs
        **kwargs: Any,
    ):
        self.config, self.grid_config = make_configs(config, grid_config, kwargs)
        super().__init__(load_map(map), self.grid_config, render_mode)
        self.arena = build_arena(self.grid_map, self.config, self.grid_config.fov_side)
        self.model = compile_arena(self.arena)
        self.flight = Flight(self.model, self.grid_map, self.config, coverage=self.mdp.coverage)
        self.data = self.flight.data
        self.unit_energy = unit_energy(self.config)
        drag = self.flight.drag.half_rho_cda  # the guard reads the wind off the same drag law
        self.guard = (
            ReturnGuard(self.grid_map, self.unit_energy, drag) if self.config.return_guard else None
        )
        limit = (self.model.vis.global_.offwidth, self.model.vis.global_.offheight)
        size = tuple(render_size) if isinstance(render_size, (tuple, list)) else ()
        if len(size) != 2 or not all(
            type(v) is int and 0 < v <= m for v, m in zip(size, limit, strict=True)
        ):
            raise ValueError(
                f"render_size must be (width, height) within {limit}, got {render_size!r}"
            )
        self.render_size = size
        self._camera = None  # the chase camera, made by the first render()
        self._last = ActionResult()
        self._crash_reason: str | None = None

    # ------------------------------------------------------------------ the backend's part
    def _on_reset(self) -> None:
        row, col = divmod(int(self.mdp.position[0]), self.mdp.width)
        capacity = float(self.mdp.budget[0]) * self.unit_energy
        self.flight.reset(row, col, capacity, rng=self.np_random)
        self.mdp.winds.set(0, self.config.wind_speed, self.config.wind_direction)  # observed
        if self.guard is not None:
            self.guard.reset()
        self._last = ActionResult()
        self._crash_reason = None

    def _transition(self, action: int) -> StepOutcome:
        """Safety decision, then the flight; its outcome goes through the grid's rules."""
        m = self.mdp
        cell = int(m.position[0])
        if self.guard is not None:  # it may fly home instead of the policy's action
            action = self.guard.filter(cell, int(action), self._remaining())
        next_cell, rejected, lands = m.safety.decide(cell, action)
        if lands:
            result = self.flight.land(cell)
        elif rejected:
            result = self.flight.hover(cell)
        else:
            result = self.flight.move(int(next_cell))
        self._last = result
        if self.guard is not None:
            force = getattr(self.flight.controller, "disturbance", None)  # a part may lack it
            self.guard.observe(int(action), bool(rejected), result.energy, force)
        budget = math.floor(self._remaining() / self.unit_energy + 1e-9)
        out = m.apply(
            Outcome(
                next_cell=np.array([next_cell], dtype=np.int64),
                rejected=np.array([rejected], dtype=bool),
                landed=np.array([result.landed]),
                spent=m.budget - budget,  # units: whatever the energy drawn amounts to
                newly_seen=np.array([result.newly_seen], dtype=np.int64),  # the camera marked
                failed=np.array([result.failure is not None]),
            )
        )
        crashed = bool(out.crashed[0])
        self._crash_reason = result.failure or (BUDGET_EXHAUSTED if crashed else None)
        return out

    def _remaining(self) -> float:
        """J of the budget left in the pack."""
        return max(self.flight.capacity - self.flight.energy_used, 0.0)

    def render(self) -> np.ndarray | None:
        """The chase camera's view of the current state, (H, W, 3) uint8; None without a mode."""
        if self.render_mode != "rgb_array":
            return None
        if self._camera is None:
            from cpp_mujoco.review.rendering import chase_camera

            # the coverage row is marked in place by the flight: the seen cells light up live
            self._camera = chase_camera(self.model, *self.render_size, coverage=self.mdp.coverage)
            # freed at exit too: a GL context left to interpreter teardown fails noisily
            self._free_camera = weakref.finalize(self, self._camera.close)
        return self._camera.render(self.data)

    def close(self) -> None:
        if self._camera is not None:
            self._free_camera()
            self._camera = None
        super().close()

    # ------------------------------------------------------------------ views
    def _info(self) -> dict[str, Any]:
        f = self.flight
        return {
            **super()._info(),
            "energy_used_j": float(f.energy_used),
            "flight_time_s": float(f.time),
            "nfz_violations": int(f.nfz_violations),
            "max_track_error_m": float(f.max_track_error),
            "tracking_error_m": float(self._last.tracking_error),
            "state_of_charge": float(f.battery.soc),
            "battery_voltage_v": float(f.battery.voltage),
            "crash_reason": self._crash_reason,
            # the return guard chose this step's action; how often it did this episode
            "guard_active": bool(self.guard is not None and self.guard.active),
            "guard_takeovers": int(self.guard.takeovers if self.guard is not None else 0),
        }
