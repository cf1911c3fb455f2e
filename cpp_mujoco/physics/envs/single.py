"""``cpp_mujoco/MuJoCo-v0``: the grid MDP's actions flown by a MuJoCo quadrotor.

Same spaces, reset options and info keys as ``cpp_mujoco/Grid-v0`` (both derive from
:class:`~cpp_mujoco.grid.single_env.SingleGridEnv`), so a grid agent runs unchanged. What changes
is where the outcome of an action comes from: the safety controller still decides it (the very
same :class:`SafetyController`), but the move is flown, coverage is what the camera footprint
saw, and the budget is the LiPo pack's remaining drawable energy in calibrated units (a calm
move's energy drawn from the pack, I²R loss included; ``info`` adds ``state_of_charge`` and
``battery_voltage_v``). The flight is the vector env's, a batch of one
(:class:`~cpp_mujoco.physics.envs.episodes.FlightEpisodes`); its outcome goes through
:meth:`GridMDP.apply`, the grid's own rules for reward, crash and termination.
"""

from __future__ import annotations

import os
import weakref
from collections.abc import Callable
from dataclasses import fields
from typing import Any

import mujoco
import numpy as np

from cpp_mujoco.grid.mdp import GridConfig, StepOutcome
from cpp_mujoco.grid.single_env import SingleGridEnv
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.envs.episodes import BUDGET_EXHAUSTED, FlightEpisodes
from cpp_mujoco.physics.parts import Controller, WindModel
from cpp_mujoco.physics.view.chase import chase_camera

__all__ = ["BUDGET_EXHAUSTED", "MuJoCoEnv", "make_configs", "split_kwargs"]


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
    ``wind_model``, ``controller_model``: a user's parts (:mod:`~cpp_mujoco.physics.parts`)
    instead of the built-in wind and controller.

    ``model`` is the MuJoCo ``MjModel``, ``data`` an ``MjData`` holding the drone's state after
    every reset and step (and at every camera frame while :attr:`on_frame` is set: a callable
    taking the env, for videos and recordings). ``render_mode="rgb_array"``: :meth:`render`
    returns the chase camera's (H, W, 3) frame (offscreen EGL/OSMesa, created on the first call
    so envs that never render never touch GL); ``render_size`` is (width, height).
    """

    def __init__(
        self,
        map: str | os.PathLike | GridMap = "A",  # noqa: A002 - the design's keyword
        config: PhysicsConfig | None = None,
        grid_config: GridConfig | None = None,
        render_mode: str | None = None,
        render_size: tuple[int, int] = (512, 384),  # multiples of 16 for video codecs
        wind_model: WindModel | None = None,
        controller_model: Controller | None = None,
        **kwargs: Any,
    ):
        self.config, self.grid_config = make_configs(config, grid_config, kwargs)
        super().__init__(load_map(map), self.grid_config, render_mode)
        self.episodes = FlightEpisodes(
            self.grid_map, self.config, self.grid_config.fov_side, self.mdp,
            controller=controller_model, wind=wind_model,
        )  # fmt: skip
        self.model, self.flight = self.episodes.model, self.episodes.flight
        self.data = mujoco.MjData(self.model)
        self.unit_energy = self.episodes.unit_energy
        self.guard = self.episodes.guards[0] if self.episodes.guards else None
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
        self._on_frame: Callable[[MuJoCoEnv], None] | None = None

    @property
    def on_frame(self) -> Callable[[MuJoCoEnv], None] | None:
        """Called with the env after every camera frame of the flight, :attr:`data` current."""
        return self._on_frame

    @on_frame.setter
    def on_frame(self, hook: Callable[[MuJoCoEnv], None] | None) -> None:
        self._on_frame = hook
        self.flight.on_frame = None if hook is None else self._frame

    def _frame(self, drone: int) -> None:
        self.flight.copy_data(drone, self.data)
        self._on_frame(self)

    @property
    def footprint(self):
        """Ground corners of the camera image now (None: the horizon is in view)."""
        return self.flight.footprint(0)

    # ------------------------------------------------------------------ the backend's part
    def _on_reset(self) -> None:
        self.episodes.reset(self.mdp, np.array([0]), [self.np_random])
        self.flight.copy_data(0, self.data)

    def _transition(self, action: int) -> StepOutcome:
        out = self.episodes.transition(self.mdp, np.array([action]), np.ones(1, dtype=bool))
        self.flight.copy_data(0, self.data)
        return out

    def render(self) -> np.ndarray | None:
        """The chase camera's view of the current state, (H, W, 3) uint8; None without a mode."""
        if self.render_mode != "rgb_array":
            return None
        if self._camera is None:
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
        physics = {k: v[0] for k, v in self.episodes.infos().items()}
        return {**super()._info(), **{k: v.item() if hasattr(v, "item") else v
                                      for k, v in physics.items()}}  # fmt: skip
