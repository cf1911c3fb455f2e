"""The per-drone state of energy, battery and wind: the arrays the compiled tick
(:mod:`~cpp_mujoco.physics.control.kernels`, :mod:`~cpp_mujoco.physics.power.kernels`) reads
and writes.

Each class takes its scalar model (:class:`~cpp_mujoco.physics.power.rotor.IntervalEnergy`,
:class:`~cpp_mujoco.physics.power.battery.Battery`, :class:`~cpp_mujoco.physics.air.wind.Wind`) for its
constants. The wind draws each drone's normals from that drone's own generator in the blocks and
order the scalar wind does, so a drone of the batch sees the very gusts a single env seeded like
it sees.
"""

from __future__ import annotations

import math

import numpy as np

from cpp_mujoco.physics.air.wind import Wind
from cpp_mujoco.physics.power.battery import _A, _B, _C, Battery
from cpp_mujoco.physics.power.rotor import IntervalEnergy


class BatchedEnergy:
    """:class:`IntervalEnergy`'s constants as the compiled ``power`` takes them: the motor
    lag's per-step weights and the forward-flight ratio's model (None: hover power)."""

    def __init__(self, scalar: IntervalEnergy):
        self.decay = np.array(scalar.decay)
        self.ff = scalar.forward


_A_B = _A / _B
_C0, _C1, _C2, _C3 = _C
_C1_2, _C2_3 = _C1 / 2, _C2 / 3


def _ocv(soc):
    c0, c1, c2, c3 = _C
    return -_A * np.exp(-_B * soc) + c0 + soc * (c1 + soc * (c2 + soc * c3))


def _ocv_integral(s):
    """A/B·(e^(−B·s) − 1) + s·(c0 + s·(c1/2 + s·(c2/3 + s·c3/4))), in that order."""
    e = np.exp(-_B * s)
    e -= 1.0
    e *= _A_B
    p = s * _C3
    p /= 4
    p += _C2_3
    p *= s
    p += _C1_2
    p *= s
    p += _C0
    p *= s
    p += e  # x + y == y + x
    return p


class BatchedBattery:
    """:class:`Battery`'s state for n packs (:attr:`failure`: why a pack could not carry its
    load)."""

    def __init__(self, spec, n: int):
        self.spec = spec
        self.charge_c = np.full(n, math.inf)
        self.soc = np.full(n, spec.reference_soc)
        self.current = np.zeros(n)
        self.drawn_j, self.load_j, self.loss_j = np.zeros(n), np.zeros(n), np.zeros(n)
        self.below_cutoff = np.zeros(n, dtype=bool)
        self.failure = np.full(n, None, dtype=object)
        self._scalar = Battery(spec)
        self._f_soc = _ocv_integral(self.soc)  # F(soc) per pack, for the next draw's f0

    def reset(self, i: int, capacity_j: float) -> None:
        b = self._scalar
        b.reset(capacity_j)
        self.charge_c[i], self.soc[i], self.current[i] = b.charge_c, b.soc, 0.0
        self.drawn_j[i] = self.load_j[i] = self.loss_j[i] = 0.0
        self.below_cutoff[i], self.failure[i] = False, None
        self._f_soc[i] = _ocv_integral(self.soc[i : i + 1])[0]

    def voltage(self) -> np.ndarray:
        s = self.spec
        return s.cells * _ocv(self.soc) - self.current * s.resistance


class NoiseBlocks:
    """Per drone, the standard normals its scalar model would pop: blocks of ``size`` drawn
    from the drone's generator when the last one runs out, taken from the end. A row holds
    the normals left and, once :meth:`refill` has drawn the next block, that block below
    them: popped from the end, the same sequence (the compiled tick pops the rows itself)."""

    SPARE = 8  # the most normals one take asks for

    def __init__(self, n: int, size: int):
        self.size = size
        self.block = np.zeros((n, size + self.SPARE))
        self.left = np.zeros(n, dtype=np.int64)
        self.rngs: list = [None] * n

    def reset(self, i: int, rng: np.random.Generator) -> None:
        self.rngs[i], self.left[i] = rng, 0

    def refill(self, i: np.ndarray, count: int) -> None:
        """Drones of ``i`` with fewer than ``count`` normals left draw their next block now,
        in the take that needs it, as the scalar model does."""
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


class BatchedWind:
    """:class:`Wind` (steady + Ornstein-Uhlenbeck gusts + Dryden turbulence) for n drones; the
    turbulence coefficients come from the scalar model's own table, keyed the same way."""

    def __init__(self, scalar: Wind, n: int):
        self.s = scalar
        # per drone: the steady wind and the turbulence's u axis (one weather may blow from
        # several directions in one batch, :meth:`set_direction`)
        self.steady = np.tile(np.array(scalar.steady, dtype=float), (n, 1))
        self.axis = np.tile(np.array(scalar.axis, dtype=float), (n, 1))
        self.gust = np.zeros((n, 2))
        self.gust_noise = NoiseBlocks(n, 512)
        self.turb = scalar.turbulence
        self.turb_noise = NoiseBlocks(n, 1000)
        self.state = np.zeros((n, 5))
        self.last = np.zeros((n, 3))
        self.has_last = np.zeros(n, dtype=bool)

    def set_direction(self, i: int, scalar: Wind) -> None:
        """Drone ``i`` flies ``scalar``'s steady wind and axes from now on: a :class:`Wind` of
        the same weather from another direction (gusts and turbulence are the same model)."""
        self.steady[i] = scalar.steady
        self.axis[i] = scalar.axis

    def reset(self, i: int, rng: np.random.Generator) -> None:
        """As :meth:`Wind.reset`: the gusts' normals first, then the turbulence's."""
        s = self.s
        self.gust_noise.reset(i, rng)
        self.turb_noise.reset(i, rng)
        one = np.array([i])
        self.gust[i] = self.gust_noise.take(one, 2)[0] * s.std if s.std else 0.0
        self.has_last[i] = False
        if self.turb is not None:
            self.state[i] = self.turb_noise.take(one, 5)[0]
