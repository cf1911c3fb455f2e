"""Wind: a steady component, optional Ornstein-Uhlenbeck gusts and optional Dryden turbulence,
acting through quadratic body drag.

The drag F = ½ρ·C_dA·|v_rel|·v_rel (v_rel = wind − body velocity) is applied at the centre of
mass through ``xfrc_applied``; thrust must tilt and grow to hold against it, which is what makes
a headwind cost energy. The wind is a swappable part of the flight (any
:class:`~cpp_mujoco.physics.parts.WindModel`); the drag belongs to the airframe. The rules run in
the tick's kernels (:func:`~cpp_mujoco.physics.tick_kernels.wind`); this module holds their
constants and each drone's state.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

from cpp_mujoco.physics import tick_kernels as kernels
from cpp_mujoco.physics.air.turbulence import DrydenParams, DrydenTurbulence
from cpp_mujoco.physics.kernel_constants import MAX_KEYS, control_constants

if TYPE_CHECKING:
    from cpp_mujoco.physics.config import PhysicsConfig


class NoiseBlocks:
    """Per drone, standard normals drawn from the drone's generator in blocks of ``size`` when
    the last block runs out, popped from the end. A row holds the normals left and, once
    :meth:`refill` has drawn the next block, that block below them: popped from the end, one
    sequence per generator whatever the take sizes (the compiled tick pops the rows itself)."""

    SPARE = 8  # the most normals one take asks for

    def __init__(self, n: int, size: int):
        self.size = size
        self.block = np.zeros((n, size + self.SPARE))
        self.left = np.zeros(n, dtype=np.int64)
        self.rngs: list = [None] * n

    def reset(self, i: int, rng: np.random.Generator) -> None:
        self.rngs[i], self.left[i] = rng, 0

    def refill(self, i: np.ndarray, count: int) -> None:
        """Drones of ``i`` with fewer than ``count`` normals left draw their next block now."""
        size = self.size
        for d in i[self.left[i] < count].tolist():
            left = self.left[d]
            self.block[d, size : size + left] = self.block[d, :left].copy()
            self.block[d, :size] = self.rngs[d].standard_normal(size)
            self.left[d] = size + left

    def take(self, i: np.ndarray, count: int) -> np.ndarray:
        """(len(i), count) normals, in pop order, for drones ``i`` (a reset's first draw)."""
        self.refill(i, count)
        left = self.left[i]
        out = self.block[i[:, None], left[:, None] - 1 - np.arange(count)]
        self.left[i] = left - count
        return out


def _steady_and_axis(config: PhysicsConfig) -> tuple[tuple, tuple]:
    sx, sy, sz = config.wind_vector
    speed = math.hypot(sx, sy)
    axis = (sx / speed, sy / speed) if speed > 0 else (1.0, 0.0)  # u direction, world xy
    return (sx, sy, sz), axis


class Wind:
    """The default wind of ``n`` drones, advanced by ``dt`` (the control interval) per tick,
    uniform in space: ``config``'s steady wind, plus exact-discretised OU gusts per horizontal
    axis (``gust_std``), plus Dryden turbulence (``turbulence``,
    :mod:`~cpp_mujoco.physics.air.turbulence`).

    Turbulence axes: u along the steady wind (east when calm), v across it, w up; fixed per
    episode. At low altitude σ_u = σ_v and L_u = L_v, so the horizontal axes only decide which
    component has the longitudinal correlation shape; axes that turned with the UAV's relative
    wind would re-project the filter states and make the gust jump when that wind reverses
    between moves. The airspeed in the time scales, |steady + OU − UAV velocity|, is taken every
    tick; the UAV's velocity is the change of its position since the last tick (zero on the
    first tick after reset). Each drone draws its normals from its own generator, the gusts'
    first: a drone of a batch sees the gusts a single env seeded like it sees.
    """

    def __init__(self, config: PhysicsConfig, dt: float, n: int = 1):
        self.config, self.dt = config, dt
        self.std = config.gust_std
        self.decay = math.exp(-dt / config.gust_tau) if config.gust_std > 0 else 0.0
        self.kick = config.gust_std * math.sqrt(1.0 - self.decay**2)
        self.turbulence: DrydenTurbulence | None = None
        if config.turbulence != "none":
            params = DrydenParams.low_altitude(config.turbulence, config.altitude)
            self.turbulence = DrydenTurbulence(params, dt)
        steady, axis = _steady_and_axis(config)
        # per drone: the steady wind and the turbulence's u axis (one weather may blow from
        # several directions in one batch, :meth:`set_direction`)
        self.steady = np.tile(np.array(steady, dtype=float), (n, 1))
        self.axis = np.tile(np.array(axis, dtype=float), (n, 1))
        self.gust = np.zeros((n, 2))
        self.gust_noise = NoiseBlocks(n, 512)
        self.turb_noise = NoiseBlocks(n, 1000)
        self.state = np.zeros((n, 5))  # the turbulence filters: u; v, v'; w, w'
        self.last = np.zeros((n, 3))
        self.has_last = np.zeros(n, dtype=bool)
        # turbulence coefficients by rounded airspeed (rows 16 wide), tabled as they are met
        self.table, self.filled = np.zeros((0, 16)), np.zeros(0, dtype=bool)
        self.keys = np.zeros(n)

    def set_direction(self, i: int, direction: float) -> None:
        """Drone ``i``'s steady wind blows from ``direction`` (degrees, as ``wind_direction``)
        from now on; gusts and turbulence are the same model."""
        config = dataclasses.replace(self.config, wind_direction=float(direction))
        self.steady[i], self.axis[i] = _steady_and_axis(config)

    def reset(self, i: int, rng: np.random.Generator) -> None:
        """Drone ``i`` starts an episode: gusts and turbulence drawn from their stationary
        distributions (the gusts' normals first, then the turbulence's)."""
        self.gust_noise.reset(i, rng)
        self.turb_noise.reset(i, rng)
        one = np.array([i])
        self.gust[i] = self.gust_noise.take(one, 2)[0] * self.std if self.std else 0.0
        self.has_last[i] = False
        if self.turbulence is not None:
            self.state[i] = self.turb_noise.take(one, 5)[0]

    def supply(self, need: int, drones: np.ndarray, kernels) -> None:
        """What a kernel asked for before it could step ``drones``: their next noise blocks
        (NEED_NOISE, the gusts' before the turbulence's) or the turbulence coefficients of
        the table keys it wrote into :attr:`keys` (NEED_COEFFICIENTS)."""
        if need == kernels.NEED_NOISE:
            if self.std:
                self.gust_noise.refill(drones, 2)
            if self.turbulence is not None:
                self.turb_noise.refill(drones, 5)
        else:
            self.tabulate(self.keys[: drones.size])

    def tabulate(self, keys: np.ndarray) -> None:
        """Table the turbulence coefficients of ``keys`` (rounded log airspeeds; keys past
        ``MAX_KEYS`` or negative are left out: those drones' turbulence turns NaN)."""
        turb = self.turbulence
        for key in np.unique(keys).tolist():
            if not 0 <= key < MAX_KEYS:
                continue
            row = int(key)
            if row >= len(self.filled):
                size = max(row + 1, 2 * len(self.filled), 256)
                self.table = np.concatenate([self.table, np.zeros((size - len(self.table), 16))])
                self.filled = np.concatenate([self.filled, np.zeros(size - len(self.filled), bool)])
            if not self.filled[row]:
                self.table[row] = turb.coefficients(math.exp(key / turb.per_log))
                self.filled[row] = True

    def velocity(self, drones: np.ndarray, time: np.ndarray, position: np.ndarray) -> np.ndarray:
        """The wind (m, 3) drones ``drones`` at ``position`` (m, 3) fly in this tick; their
        gusts and turbulence advance one tick (:class:`~cpp_mujoco.physics.parts.WindModel`)."""
        drones = np.asarray(drones, dtype=np.int64)
        pos = np.ascontiguousarray(position, dtype=float)
        c, out = control_constants(self.dt, wind=self), np.empty((drones.size, 3))
        while True:
            need = kernels.wind(
                drones, pos, c, self.steady, self.axis, self.gust, self.gust_noise.block,
                self.gust_noise.left, self.state, self.turb_noise.block, self.turb_noise.left,
                self.last, self.has_last, self.table, self.filled, self.keys, out,
            )  # fmt: skip
            if need == 0:
                return out
            self.supply(need, drones, kernels)
