"""Energy, battery and wind over N drones at once: the array twins of the single flight's models.

Each class takes its scalar model (:class:`~cpp_mujoco.physics.energy.IntervalEnergy`,
:class:`~cpp_mujoco.physics.battery.Battery`, :class:`~cpp_mujoco.physics.wind.Wind`) for its
constants and keeps the state per drone, evaluating the same expressions in the same order (see
:mod:`~cpp_mujoco.physics.batched_control` for why). The wind draws each drone's normals from that
drone's own generator in the blocks and order the scalar wind does, so a drone of the batch sees
the very gusts a single env seeded like it sees.
"""

from __future__ import annotations

import math

import numpy as np

from cpp_mujoco.physics.battery import _A, _B, _C, OVERLOAD, Battery
from cpp_mujoco.physics.energy import IntervalEnergy
from cpp_mujoco.physics.wind import Wind

_SQRT3 = math.sqrt(3.0)


class BatchedEnergy:
    """:class:`IntervalEnergy` (with its forward-flight ratio, if any) for n drones. The
    per-step terms of all drones are one (substeps, n, 4) array: a handful of numpy calls per
    tick instead of one per term."""

    def __init__(self, scalar: IntervalEnergy):
        self.s = scalar
        self.decay = np.array(scalar.decay)
        self._weights = self.decay[:, None, None]
        self.ff = scalar.forward
        p = scalar.power
        self._coef, self._idle, self._dt = p.coef, p.avionics * len(scalar.decay), scalar.dt

    def __call__(self, act0: np.ndarray, ctrl: np.ndarray, air: np.ndarray | None) -> np.ndarray:
        """J of one control interval per drone: (n, 4) rotor states and commands, (n, 3) air."""
        d = act0 - ctrl
        t = ctrl + d * self._weights  # (substeps, n, 4): the rotor state of every step
        p = t * np.sqrt(t)
        rotor = p[0].copy()  # summed step by step, as the scalar loop does (0.0 + x is x)
        for k in range(1, len(p)):
            rotor += p[k]
        if self.ff is not None and air is not None:
            t = ctrl + d * self.s.mean_decay
            v_par = np.hypot(air[:, 0], air[:, 1])[:, None]
            v_perp = air[:, 2][:, None]
            if np.count_nonzero(t > 0.0) == t.size:  # the common case, without the masks
                rotor *= self.ratio(t, v_par, v_perp)
            else:
                positive = t > 0.0
                ratio = self.ratio(np.where(positive, t, 1.0), v_par, v_perp)
                rotor = np.where(positive, rotor * ratio, rotor)
        total = rotor[:, 0] + rotor[:, 1]
        total += rotor[:, 2]
        total += rotor[:, 3]
        total *= self._coef
        total += self._idle
        total *= self._dt
        return total

    def ratio(self, thrust, v_par, v_perp) -> np.ndarray:
        """:meth:`ForwardFlightPower.ratio` elementwise (thrust > 0); ``v_par``, ``v_perp``
        (n, 1). In-place updates keep each expression's order (see the scalar ``_solve``)."""
        ff = self.ff
        vh2 = thrust * ff.inv_2rho_a
        vh = np.sqrt(vh2)
        vp = np.maximum(v_perp, -ff.vrs * vh)
        v = np.sqrt(0.25 * vp * vp + vh2)
        v += -0.5 * vp
        moving = v_par != 0.0
        n_moving = np.count_nonzero(moving)
        if n_moving:
            vpar = v_par if n_moving == len(v_par) else np.where(moving, v_par, 1.0)
            vpar2, vh4 = vpar * vpar, vh2 * vh2
            w = np.where(vh2 < v * vpar, vh2 / vpar, v)
            if n_moving < len(v_par):
                w = np.where(moving, w, v)
            sw, q, num, den = (np.empty_like(w) for _ in range(4))
            for _ in ff.steps:
                np.add(w, vp, out=sw)  # s = v + vp
                np.multiply(sw, sw, out=q)
                q += vpar2  # q = s·s + vpar²
                np.multiply(w, w, out=num)
                num *= q
                num -= vh4  # v·v·q − vh⁴
                np.multiply(w, sw, out=den)
                den += q
                np.multiply(2.0 * w, den, out=den)  # 2v·(q + v·s)
                num /= den
                w -= num
            v = w if n_moving == len(v_par) else np.where(moving, w, v)
        mu2 = v_par * v_par * ff.ct_rho_a / thrust
        r = ff.kappa * v
        r += ff.fm * vp
        r /= vh
        mu2 *= ff.k_mu
        mu2 += 1.0
        mu2 *= ff.p0
        r += mu2
        return np.maximum(r, 0.0, out=r)


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
    """:class:`Battery` for n packs: ``draw`` returns the chemical J per drone, NaN where the
    pack cannot carry the load (its :attr:`failure` then says why)."""

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

    def draw(self, i: np.ndarray, power: np.ndarray, dt: float) -> np.ndarray:
        """:meth:`Battery.draw` for packs ``i``: chemical J each, NaN where it cannot."""
        s = self.spec
        n, r, q, s0 = s.cells, s.resistance, self.charge_c[i], self.soc[i]
        if np.isfinite(q).all() and (power > 0.0).all():
            fast = self._draw_finite(i, power, dt, n, r, q, s0)
            if fast is not None:
                return fast
        finite = np.isfinite(q)
        qs = np.where(finite, q, 1.0)
        f0 = _ocv_integral(s0)  # the same double every pass: computed once
        ok = np.ones(power.shape, dtype=bool)

        def current_of(v):
            disc = v * v - 4.0 * r * power
            ok[disc < 0.0] = False
            c = 2.0 * power / (v + np.sqrt(np.maximum(disc, 0.0)))
            return np.where(power <= 0.0, 0.0, c)

        def mean_ocv(go, current, s1, v):  # the OCV averaged over the tick's charge
            s1 = np.where(go, s0 - current * dt / qs, s1)
            with np.errstate(divide="ignore", invalid="ignore"):
                mean = n * (f0 - _ocv_integral(s1)) / (s0 - s1)
            return s1, np.where(go, mean, v)

        v = n * _ocv(s0)
        current = current_of(v)
        s1 = s0
        for _ in range(3):
            go = finite & (current != 0.0) & ok
            if not go.any():
                break
            s1, v = mean_ocv(go, current, s1, v)
            current = np.where(go, current_of(v), current)
        s1, v = mean_ocv(finite & (current > 0.0), current, s1, v)
        loss = current * current * r * dt
        chem = v * current * dt
        good, bad = i[ok], i[~ok]
        self.soc[good] = np.maximum(s1[ok], 0.0)
        self._f_soc[good] = _ocv_integral(self.soc[good])
        self.current[good] = current[ok]
        self.below_cutoff[good] = (v - current * r < n * s.cutoff_v)[ok]
        self.drawn_j[good] += chem[ok]
        self.load_j[good] += np.where(power > 0.0, power * dt, 0.0)[ok]
        self.loss_j[good] += loss[ok]
        self.failure[bad] = OVERLOAD
        return np.where(ok, chem, np.nan)

    def _draw_finite(self, i, power, dt, n, r, q, s0) -> np.ndarray | None:
        """:meth:`draw` when every pack is finite, loaded and able to carry its load (the
        common case, without the masks); None when one is not (then the general path runs:
        nothing has changed yet). ``F(s0)`` is the one the last draw ended on, kept per pack
        (:attr:`_f_soc`): the same double, not computed again."""
        f0 = self._f_soc[i]
        four_rp = 4.0 * r * power
        two_p = 2.0 * power
        v = n * _ocv(s0)
        dmin = None
        with np.errstate(invalid="ignore"):  # a pack that cannot: NaNs, then the general path
            for _ in range(4):  # the first current, then three passes of the mean OCV
                disc = v * v
                disc -= four_rp
                dmin = disc if dmin is None else np.fmin(dmin, disc, out=dmin)
                current = np.sqrt(disc)
                current += v
                np.divide(two_p, current, out=current)
                s1 = current * dt
                s1 /= q
                np.subtract(s0, s1, out=s1)
                f1 = _ocv_integral(s1)
                v = f0 - f1
                v *= n
                v /= s0 - s1
        if np.count_nonzero(dmin < 0.0):
            return None
        loss = current * current * r * dt
        chem = v * current * dt
        soc = np.maximum(s1, 0.0)
        self.soc[i] = soc
        clipped = s1 < 0.0  # soc 0 (F(0) = 0.0, as _ocv_integral gives it)
        if np.count_nonzero(clipped):
            f1[clipped] = _ocv_integral(soc[clipped])
        self._f_soc[i] = f1
        self.current[i] = current
        self.below_cutoff[i] = v - current * r < n * self.spec.cutoff_v
        self.drawn_j[i] += chem
        self.load_j[i] += power * dt
        self.loss_j[i] += loss
        return chem


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
        """(len(i), count) normals, in pop order, for drones ``i``."""
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
        self._rows: dict = {}
        self._table = np.zeros((0, 16))
        if self.turb is not None:
            self.gain = np.array(self.turb._gain)

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

    def _coefficients(self, airspeed: np.ndarray) -> np.ndarray:
        t = self.turb
        airspeed = np.maximum(airspeed, t.min_airspeed)
        if t._per_log:
            keys = np.round(np.log(airspeed) * t._per_log)
        else:
            keys = airspeed
        unique, inverse = np.unique(keys, return_inverse=True)
        rows = []
        for key in unique.tolist():
            row = self._rows.get(key)
            if row is None:
                speed = math.exp(key / t._per_log) if t._per_log else key  # as the scalar's
                row = self._rows[key] = len(self._table)
                self._table = np.vstack([self._table, np.array(t._coefficients(speed))])
            rows.append(row)
        return self._table[np.array(rows)[inverse]]

    def velocity(self, i: np.ndarray, pos: np.ndarray, dt: float) -> np.ndarray:
        """(n, 3) wind at drones ``i`` at world ``pos``; advances their gusts one interval."""
        s = self.s
        w = self.steady[i]  # a copy (fancy indexing)
        if s.std:
            g = self.gust[i]
            noise = self.gust_noise.take(i, 2)
            g0 = g[:, 0] * s.decay + s.kick * noise[:, 0]
            g1 = g[:, 1] * s.decay + s.kick * noise[:, 1]
            self.gust[i] = np.stack([g0, g1], 1)
            w[:, 0] += g0
            w[:, 1] += g1
        if self.turb is None:
            return w
        rel = w.copy()
        had = self.has_last[i]
        k = 1.0 / s.dt
        moved = rel - (pos - self.last[i]) * k
        rel = np.where(had[:, None], moved, rel)
        self.last[i], self.has_last[i] = pos, True
        coef = self._coefficients(
            np.sqrt(rel[:, 0] * rel[:, 0] + rel[:, 1] * rel[:, 1] + rel[:, 2] * rel[:, 2])
        )
        au, ku, v11, v12, v21, v22, vl11, vl21, vl22, w11, w12, w21, w22, wl11, wl21, wl22 = coef.T
        u, v1, v2, w1, w2 = self.state[i].T
        nz = self.turb_noise.take(i, 5)
        u = au * u + ku * nz[:, 0]
        a, b = nz[:, 1], nz[:, 2]
        v1, v2 = v11 * v1 + v12 * v2 + vl11 * a, v21 * v1 + v22 * v2 + vl21 * a + vl22 * b
        a, b = nz[:, 3], nz[:, 4]
        w1, w2 = w11 * w1 + w12 * w2 + wl11 * a, w21 * w1 + w22 * w2 + wl21 * a + wl22 * b
        self.state[i] = np.stack([u, v1, v2, w1, w2], 1)
        gu, gv, gw = self.gain
        gust_u, gust_v, gust_w = gu * u, gv * (v1 + _SQRT3 * v2), gw * (w1 + _SQRT3 * w2)
        cx, cy = self.axis[i, 0], self.axis[i, 1]
        return np.stack(
            [w[:, 0] + gust_u * cx - gust_v * cy, w[:, 1] + gust_u * cy + gust_v * cx,
             w[:, 2] + gust_w],
            1,
        )  # fmt: skip
