"""The flight's control tick: the Python around the compiled kernels of
:mod:`~cpp_mujoco.physics.tick_kernels` and :mod:`~cpp_mujoco.physics.power.kernels`.

Why: as numpy arrays a tick is ≈ 150 calls over short arrays and costs about half as long as
MuJoCo's five physics steps between ticks at 128 drones (more than them at one drone); compiled,
it is three calls (sense, control, power) that cost a few percent of them.

On a map with obstacles the tick begins with the obstacle check
(:class:`~cpp_mujoco.physics.obstacles.ObstacleCrashes`, compiled too). The kernels flag what
stays in Python, drone by drone and rarely: the failure messages, the
camera frames due, the ground contacts and time limits of landing or falling drones, the
battery's overload and failsafe, a noise block that runs out, turbulence coefficients not yet
tabled. A user's wind or controller part (:mod:`~cpp_mujoco.physics.parts`) is called here,
between ``sense`` and ``control``, for the drones that fly on.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cpp_mujoco.physics import tick_kernels as control_kernels
from cpp_mujoco.physics.action import FAILURES, MacroActions
from cpp_mujoco.physics.kernel_constants import control_constants
from cpp_mujoco.physics.power import kernels as power_kernels
from cpp_mujoco.physics.power.battery import OVERLOAD

if TYPE_CHECKING:
    from cpp_mujoco.physics.flight import Flight


class Tick:
    """One control tick of a :class:`~cpp_mujoco.physics.flight.Flight`: ``tick(i, action)``
    returns the drones that step next."""

    def __init__(self, flight: Flight):
        self.k, self.p, self.f, self.failures = control_kernels, power_kernels, flight, FAILURES
        c, geo, (bx, by, bz) = flight.config, flight.geo, flight.bounds
        self.sense_c = np.array([
            bx, by, bz, flight.cos_flip, geo.height, geo.width, 1.0 / geo.cell_size, flight.k,
            flight.controller.lead, c.land_duration, c.land_speed, c.max_tracking_error**2,
            c.arrive_pos_tol**2, c.arrive_vel_tol**2, c.fall_time_limit,
        ], dtype=float)  # fmt: skip
        law = flight.law
        self.control_c = control_constants(
            flight.dt,
            flight.weather,
            law,
            flight.energy_of,
            flight.battery.spec,
            flight.half_rho_cda,
        )
        ff = flight.energy_of.forward
        self.ff = ff.constants() if ff is not None else np.zeros(9)
        q, v, a = flight.cols
        self.cols = np.array(
            [q.start, v.start, a.start, flight.ctrl_cols.start, flight.force_cols.start]
        )
        n = flight.n
        self.code = np.zeros(n, dtype=np.int64)
        self.R, self.ref = np.zeros((n, 9)), np.zeros((n, 9))
        self.lists = np.zeros((3, n), dtype=np.int32)  # int32: the batch's ids, not converted
        self.air, self.flags = np.zeros((n, 3)), np.zeros(n, dtype=np.int8)
        # a user's parts, called from Python: 1 the wind, 2 the thrusts come given
        self.given = (flight.wind is not flight.weather) + 2 * (flight.controller is not law)
        self._action: MacroActions | None = None  # the action the bound arguments are of

    def _bind(self, a: MacroActions) -> None:
        """The kernels' arguments but the drones and their codes, for action ``a``: arrays that
        live as long as the action (bound once, not gathered every tick)."""
        f, refs, ctl, w, b = self.f, self.f.refs, self.f.law, self.f.weather, self.f.battery
        self._action = a
        self._sense = (
            f.state, self.cols[0], self.cols[1], self.sense_c, f.motors_on, f._bad, f._bad0,
            f.no_fly, f.nfz_violations, f._ncon, f.camera.next_frame, refs.start, refs.delta,
            refs.duration, refs.descent, refs.end, a.t, a.t0, a.goal, a.nominal, a.limit,
            a.arrive, a.land, a.worst2, a.flying, a.res["arrived"], self.R, self.ref,
        )  # fmt: skip
        self._control_args = (
            f.state, self.cols, self.control_c, self.R, self.ref, f.motors_on,
            ctl.A_inv, ctl.integral, ctl.disturbance, ctl.last_vel, ctl.last_force,
            ctl.has_last, w.steady, w.axis, w.gust, w.gust_noise.block, w.gust_noise.left,
            w.state, w.turb_noise.block, w.turb_noise.left, w.last, w.has_last, w.table,
            w.filled, w.keys, self.air, f.wind_now, self.given,
        )  # fmt: skip
        self._power = (
            f.state, self.cols, self.control_c, self.air, f.motors_on, a.t, f.energy_used,
            f.capacity, f.energy_of.decay, self.ff, b.charge_c, b.soc, b.current, b.drawn_j,
            b.load_j, b.loss_j, b.below_cutoff, b.f_soc, self.flags,
        )  # fmt: skip

    def __call__(self, i: np.ndarray, a: MacroActions) -> np.ndarray:
        K, f = self.k, self.f
        if a is not self._action:
            self._bind(a)
        if f.obstacles is not None:  # a drone that touches an obstacle fails here
            i = f.obstacles(i, f._live[0], a.res["failure"], a.flying)
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
            if self.given:
                self._user_parts(i, ids, code)
            self._control(i, ids, code, a)
        return ids

    def _user_parts(self, i: np.ndarray, go: np.ndarray, code: np.ndarray) -> None:
        """A user's wind (into ``wind_now``) and rotor thrusts (into the ctrl rows, clipped to
        the rotors' range) for drones ``go``; drones with motors off get no thrust."""
        f = self.f
        q, v, a = f.cols
        st = f.state
        pos, vel = st[go, q][:, :3], st[go, v]
        if self.given & 1:
            f.wind_now[go] = f.wind.velocity(go, st[go, 0], pos)
        if self.given & 2:
            rows = np.flatnonzero(code[: i.size] & 7 == self.k.FLY)
            on = f.motors_on[go]
            drones = go[on]
            thrust = f.controller(
                drones, pos[on], vel[on, :3], self.R[rows[on]].reshape(-1, 3, 3), vel[on, 3:],
                st[drones, a], self.ref[rows[on]].reshape(-1, 3, 3), f.dt,
            )  # fmt: skip
            st[drones, f.ctrl_cols] = np.clip(thrust, 0.0, f.law.f_max)

    def _control(self, i: np.ndarray, go: np.ndarray, code: np.ndarray, a: MacroActions) -> None:
        """The inputs of the drones ``go`` (those of ``i`` whose ``code`` is FLY)."""
        K, f = self.k, self.f
        while True:
            need = K.control(i, code, *self._control_args)
            if need == 0:
                break
            if need == K.NEED_NOISE:
                f.weather.supply(need, go, K)
            else:
                f.weather.tabulate(f.weather.keys[: i.size][code & 7 == K.FLY])
                self._bind(a)  # the table may have grown into new arrays
        flagged = self.p.power(go, *self._power)
        if flagged:
            flags = self.flags[: go.size]
            f.battery.failure[go[flags == 1]] = OVERLOAD
            d = go[flags == 2]
            d = d[~a.begun_landing[d] & (a.emergency[d] == None)]  # noqa: E711
            if d.size:
                f._failsafe(d, f.state[d, f.cols[0]][:, :3], a)
