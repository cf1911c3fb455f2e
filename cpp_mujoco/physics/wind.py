"""Wind: a steady component plus Ornstein-Uhlenbeck gusts, acting through quadratic body drag.

The drag F = ½ρ·C_dA·|v_rel|·v_rel (v_rel = wind − body velocity) is applied at the centre of
mass through ``xfrc_applied``; thrust must tilt and grow to hold against it, which is what makes
a headwind cost energy.
"""

from __future__ import annotations

import math

import numpy as np

from cpp_mujoco.physics.config import PhysicsConfig


class Wind:
    """Horizontal wind velocity over time; gusts are an exact-discretised OU process per axis."""

    def __init__(self, config: PhysicsConfig, dt: float, drag_area: float):
        self.steady = config.wind_vector
        self.std = config.gust_std
        self.decay = math.exp(-dt / config.gust_tau) if config.gust_std > 0 else 0.0
        self.kick = config.gust_std * math.sqrt(1.0 - self.decay**2)
        self.half_rho_cda = 0.5 * config.air_density * drag_area
        self.gust = [0.0, 0.0]
        self._noise: list[float] = []
        self._rng: np.random.Generator | None = None

    def reset(self, rng: np.random.Generator) -> None:
        """Start a new episode: gusts drawn from their stationary distribution."""
        self._rng = rng
        self._noise = []
        self.gust = [self._normal() * self.std, self._normal() * self.std] if self.std else [0, 0]

    def _normal(self) -> float:
        if not self._noise:  # draw in blocks: one numpy call per 512 samples
            self._noise = self._rng.standard_normal(512).tolist()
        return self._noise.pop()

    def velocity(self) -> tuple[float, float, float]:
        """Current wind velocity, then advance the gusts by one control interval."""
        sx, sy, sz = self.steady
        if self.std:
            g = self.gust
            g[0] = g[0] * self.decay + self.kick * self._normal()
            g[1] = g[1] * self.decay + self.kick * self._normal()
            return sx + g[0], sy + g[1], sz
        return sx, sy, sz

    def drag(self, vel, wind) -> tuple[float, float, float]:
        """Drag force (N, world frame) on a body moving at ``vel`` in air moving at ``wind``."""
        rx, ry, rz = wind[0] - vel[0], wind[1] - vel[1], wind[2] - vel[2]
        k = self.half_rho_cda * math.sqrt(rx * rx + ry * ry + rz * rz)
        return k * rx, k * ry, k * rz
