"""The batched flight's control tick: the Python around the compiled kernels of
:mod:`~cpp_mujoco.physics.control.kernels` and :mod:`~cpp_mujoco.physics.power.kernels`.

Why: as numpy arrays a tick is ≈ 150 calls over short arrays and costs about half as long as
MuJoCo's five physics steps between ticks at 128 drones (more than them at one drone); compiled,
it is three calls (sense, control, power) that cost a few percent of them.

The kernels flag what stays in Python, drone by drone and rarely: the failure messages, the
camera frames due, the ground contacts and time limits of landing or falling drones, the
battery's overload and failsafe, a noise block that runs out, turbulence coefficients not yet
tabled. Everything else of a tick is arithmetic over the state arrays of
:mod:`~cpp_mujoco.physics.control.state` and :mod:`~cpp_mujoco.physics.power.state`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from cpp_mujoco.physics.batched_action import FAILURES, MacroActions
from cpp_mujoco.physics.control.controller import GRAVITY
from cpp_mujoco.physics.power.battery import _A, _B, _C, OVERLOAD

if TYPE_CHECKING:
    from cpp_mujoco.physics.batched_flight import BatchedFlight

# the cell's OCV curve as the compiled battery takes it: a, b, c0…c3, then a/b, c1/2, c2/3
OCV = (_A, _B, *_C, _A / _B, _C[1] / 2, _C[2] / 3)
# tabled turbulence time scales: airspeeds up to e^(key·0.5 %) ≈ 1e35 m/s; a drone's airspeed
# past that (or NaN) has diverged already, and its turbulence turns NaN (it fails next tick)
MAX_KEYS = 1 << 14


def control_constants(flight: BatchedFlight) -> np.ndarray:
    """The constants ``compiled_control.control`` and ``compiled_power.power`` read, in their
    order: wind (and gravity), controller, energy, battery, drag, turbulence, the OCV curve,
    the turbulence table's size limit."""
    one, w = flight.one, flight.wind.s
    c = one.controller
    e = one.interval_energy
    spec = flight.battery.spec
    turb = w.turbulence
    return np.array([
        w.std, w.decay, w.kick, GRAVITY, w.dt,
        flight.dt, c.kx, c.kv, c.mass, c.ki * flight.dt, c.i_limit, c.tan_tilt, c.min_fz,
        c.weight, c.f_max, c.obs_tau, c.obs_limit, *c.J, *c.kR, *c.kW,
        e.power.coef, e.power.avionics * len(e.decay), e.dt, e.mean_decay,
        spec.cells, spec.resistance, spec.cutoff_v, one.drag.half_rho_cda,
        turb is not None, *((turb.min_airspeed, turb._per_log, *turb._gain) if turb else [0.0] * 5),
        *OCV, MAX_KEYS,
    ], dtype=float)  # fmt: skip


class CompiledTick:
    """:meth:`BatchedFlight._tick` with the arithmetic in three kernels; called as the tick
    is: ``tick(i, action)`` returns the drones that step next."""

    def __init__(self, flight: BatchedFlight):
        from cpp_mujoco.physics.control import kernels as compiled_control
        from cpp_mujoco.physics.power import kernels as compiled_power

        self.k, self.p, self.f, self.failures = compiled_control, compiled_power, flight, FAILURES
        one, c = flight.one, flight.config
        geo, (bx, by, bz) = one.geo, one.bounds
        self.sense_c = np.array([
            bx, by, bz, one.cos_flip, geo.height, geo.width, 1.0 / geo.cell_size, flight.k,
            one.controller.lead, c.land_duration, c.land_speed, c.max_tracking_error**2,
            c.arrive_pos_tol**2, c.arrive_vel_tol**2, c.fall_time_limit,
        ], dtype=float)  # fmt: skip
        self.control_c = control_constants(flight)
        turb = flight.wind.turb
        if turb is not None and not turb._per_log:
            raise ValueError("the compiled tick tables turbulence on a rounded airspeed grid")
        ff = flight.energy_of.ff
        self.ff = np.array(
            [ff.inv_2rho_a, ff.vrs, ff.ct_rho_a, ff.kappa, ff.fm, ff.k_mu, ff.p0,
             len(ff.steps), 1.0] if ff is not None else [0.0] * 9,
        )  # fmt: skip
        q, v, a = flight.cols
        self.cols = np.array(
            [q.start, v.start, a.start, flight.ctrl_cols.start, flight.force_cols.start]
        )
        n = flight.n
        self.code = np.zeros(n, dtype=np.int64)
        self.R, self.ref, self.keys = np.zeros((n, 9)), np.zeros((n, 9)), np.zeros(n)
        self.lists = np.zeros((3, n), dtype=np.int32)  # int32: the batch's ids, not converted
        self.air, self.flags = np.zeros((n, 3)), np.zeros(n, dtype=np.int8)
        self.table, self.filled = np.zeros((0, 16)), np.zeros(0, dtype=bool)
        self.A = np.ascontiguousarray(flight.controller.A_inv)
        self._action: MacroActions | None = None  # the action the bound arguments are of

    def _bind(self, a: MacroActions) -> None:
        """The kernels' arguments but the drones and their codes, for action ``a``: arrays that
        live as long as the action (bound once, not gathered every tick)."""
        f, refs, ctl, w, b = self.f, self.f.refs, self.f.controller, self.f.wind, self.f.battery
        self._action = a
        self._sense = (
            f.state, self.cols[0], self.cols[1], self.sense_c, f.motors_on, f._bad, f._bad0,
            f.no_fly, f.nfz_violations, f._ncon, f.camera.next_frame, refs.start, refs.delta,
            refs.duration, refs.descent, refs.end, a.t, a.t0, a.goal, a.nominal, a.limit,
            a.arrive, a.land, a.worst2, a.flying, a.res["arrived"], self.R, self.ref,
        )  # fmt: skip
        self._control_args = (
            f.state, self.cols, self.control_c, self.R, self.ref, f.motors_on,
            self.A, ctl.integral, ctl.disturbance, ctl.last_vel, ctl.last_force,
            ctl.has_last, w.steady, w.axis, w.gust, w.gust_noise.block, w.gust_noise.left,
            w.state, w.turb_noise.block, w.turb_noise.left, w.last, w.has_last, self.table,
            self.filled, self.keys, self.air, f.wind_now,
        )  # fmt: skip
        self._power = (
            f.state, self.cols, self.control_c, self.air, f.motors_on, a.t, f.energy_used,
            f.capacity, f.energy_of.decay, self.ff, b.charge_c, b.soc, b.current, b.drawn_j,
            b.load_j, b.loss_j, b.below_cutoff, b._f_soc, self.flags,
        )  # fmt: skip

    def __call__(self, i: np.ndarray, a: MacroActions) -> np.ndarray:
        K, f = self.k, self.f
        if a is not self._action:
            self._bind(a)
        m, res = i.size, a.res
        code = self.code[:m]
        failed, due, go, check = K.sense(i, *self._sense, code, self.lists)
        if failed:
            kind = code & 7
            for j in np.flatnonzero((kind >= K.BROKEN) & (kind <= K.DIVERGED)).tolist():
                res["failure"][i[j]] = self.failures[kind[j] - K.BROKEN]
        if due:
            drones = self.lists[0, :due]
            res["newly_seen"][drones] += f.capture(drones)
        ids = self.lists[1, :go]
        if check:
            ended = False
            for j in self.lists[2, :check].tolist():
                d = int(i[j])
                if f._landing_done(d, a):
                    code[j], a.flying[d], ended = K.ENDED, False, True
            if ended:
                ids = i[code & 7 == K.FLY]
        if ids.size:
            self._control(i, ids, code, a)
        return ids

    def _control(self, i: np.ndarray, go: np.ndarray, code: np.ndarray, a: MacroActions) -> None:
        """The inputs of the drones ``go`` (those of ``i`` whose ``code`` is FLY)."""
        K, f = self.k, self.f
        w, b = f.wind, f.battery
        while True:
            need = K.control(i, code, *self._control_args)
            if need == 0:
                break
            if need == K.NEED_NOISE:  # each drone's gust block before its turbulence's
                if w.s.std:
                    w.gust_noise.refill(go, 2)
                if w.turb is not None:
                    w.turb_noise.refill(go, 5)
            else:
                self._tabulate(self.keys[: i.size][code & 7 == K.FLY])
                self._bind(a)  # the table may have grown into new arrays
        flagged = self.p.power(go, *self._power)
        if flagged:
            flags = self.flags[: go.size]
            b.failure[go[flags == 1]] = OVERLOAD
            d = go[flags == 2]
            d = d[~a.begun_landing[d] & (a.emergency[d] == None)]  # noqa: E711
            if d.size:
                f._failsafe(d, f.state[d, f.cols[0]][:, :3], a)

    def _tabulate(self, keys: np.ndarray) -> None:
        """Table the turbulence coefficients of ``keys`` (the scalar model's rows, keyed as
        it keys them; the kernel leaves keys off the table out)."""
        turb = self.f.wind.turb
        for key in np.unique(keys).tolist():
            if not 0 <= key < MAX_KEYS:
                continue
            row = int(key)
            if row >= len(self.filled):
                size = max(row + 1, 2 * len(self.filled), 256)
                self.table = np.concatenate([self.table, np.zeros((size - len(self.table), 16))])
                self.filled = np.concatenate([self.filled, np.zeros(size - len(self.filled), bool)])
            if not self.filled[row]:
                self.table[row] = turb._coefficients(math.exp(key / turb._per_log))
                self.filled[row] = True
