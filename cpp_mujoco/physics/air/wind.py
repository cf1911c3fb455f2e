"""Wind: a steady component, optional Ornstein-Uhlenbeck gusts and optional Dryden turbulence,
acting through quadratic body drag.

The drag F = ½ρ·C_dA·|v_rel|·v_rel (v_rel = wind − body velocity) is applied at the centre of
mass through ``xfrc_applied``; thrust must tilt and grow to hold against it, which is what makes
a headwind cost energy. The wind is a swappable part of the flight (any
:class:`~cpp_mujoco.physics.parts.WindModel`); the drag belongs to the airframe.
"""

from __future__ import annotations

import math

import numpy as np

from cpp_mujoco.physics.air.turbulence import DrydenParams, DrydenTurbulence
from cpp_mujoco.physics.config import PhysicsConfig


class Wind:
    """The default wind model, advanced by ``dt`` (the control interval) per call, uniform in
    space: ``config``'s steady wind, plus exact-discretised OU gusts per horizontal axis
    (``gust_std``), plus Dryden turbulence (``turbulence``,
:mod:`~cpp_mujoco.physics.air.turbulence`).

    Turbulence axes: u along the steady wind (east when calm), v across it, w up; fixed per
    episode. At low altitude σ_u = σ_v and L_u = L_v, so the horizontal axes only decide which
    component has the longitudinal correlation shape; axes that turned with the UAV's relative
    wind would re-project the filter states and make the gust jump when that wind reverses
    between moves. The airspeed in the time scales, |steady + OU − UAV velocity|, is taken every
    tick; the UAV's velocity is the change of the ``position`` the flight passes since the last
    call (zero on the first call after reset, and when no position is given).
    """

    def __init__(self, config: PhysicsConfig, dt: float):
        self.steady = config.wind_vector
        self.std = config.gust_std
        self.decay = math.exp(-dt / config.gust_tau) if config.gust_std > 0 else 0.0
        self.kick = config.gust_std * math.sqrt(1.0 - self.decay**2)
        self.gust = [0.0, 0.0]
        self.dt = dt
        self._noise: list[float] = []
        self._rng: np.random.Generator | None = None
        self.turbulence: DrydenTurbulence | None = None
        if config.turbulence != "none":
            params = DrydenParams.low_altitude(config.turbulence, config.altitude)
            self.turbulence = DrydenTurbulence(params, dt)
        sx, sy, _ = self.steady
        speed = math.hypot(sx, sy)
        self.axis = (sx / speed, sy / speed) if speed > 0 else (1.0, 0.0)  # u direction, world xy
        self._last: tuple[float, float, float] | None = None

    def reset(self, rng: np.random.Generator) -> None:
        """Start a new episode: gusts and turbulence drawn from their stationary distributions."""
        self._rng = rng
        self._noise = []
        self.gust = [self._normal() * self.std, self._normal() * self.std] if self.std else [0, 0]
        self._last = None
        if self.turbulence is not None:
            self.turbulence.reset(rng)

    def _normal(self) -> float:
        if not self._noise:  # draw in blocks: one numpy call per 512 samples
            self._noise = self._rng.standard_normal(512).tolist()
        return self._noise.pop()

    def velocity(self, time: float = 0.0, position=None) -> tuple[float, float, float]:
        """Current wind velocity, then advance the gusts by one control interval."""
        sx, sy, sz = self.steady
        if self.std:
            g = self.gust
            g[0] = g[0] * self.decay + self.kick * self._normal()
            g[1] = g[1] * self.decay + self.kick * self._normal()
            sx, sy = sx + g[0], sy + g[1]
        if self.turbulence is None:
            return sx, sy, sz
        rx, ry, rz = sx, sy, sz  # the mean wind relative to the UAV
        if position is not None:
            x, y, z = position[0], position[1], position[2]
            last = self._last
            if last is not None:
                k = 1.0 / self.dt
                rx, ry, rz = rx - (x - last[0]) * k, ry - (y - last[1]) * k, rz - (z - last[2]) * k
            self._last = (x, y, z)
        u, v, w = self.turbulence.step(math.sqrt(rx * rx + ry * ry + rz * rz))
        cx, cy = self.axis
        return sx + u * cx - v * cy, sy + u * cy + v * cx, sz + w


class QuadraticDrag:
    """The airframe's drag in moving air: ``½ρ·C_dA·|v_rel|·v_rel``."""

    def __init__(self, air_density: float, drag_area: float):
        self.half_rho_cda = 0.5 * air_density * drag_area

    def force(self, vel, wind) -> tuple[float, float, float]:
        """Drag force (N, world frame) on a body moving at ``vel`` in air moving at ``wind``."""
        rx, ry, rz = wind[0] - vel[0], wind[1] - vel[1], wind[2] - vel[2]
        k = self.half_rho_cda * math.sqrt(rx * rx + ry * ry + rz * rz)
        return k * rx, k * ry, k * rz
