"""The flight's control law over N drones at once: references, the geometric controller, drag.

The single flight (:mod:`~cpp_mujoco.physics.flight`) runs these laws in plain floats, because a
numpy call per tick costs more than one drone's arithmetic. Over N drones the same laws as numpy
arrays cost a few microseconds per drone instead, which is what lets the batched env
(:mod:`~cpp_mujoco.physics.vector_env`) spend its time in MuJoCo. Every expression is written in
the same order as its scalar twin, so both give the same doubles up to the last bit of a
transcendental function; ``tests/test_physics_vector_env.py`` flies both and compares.

Arrays are (n, 3) vectors, (n, 9) row-major body→world rotations, (n, 4) rotor thrusts.
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.physics.controller import GRAVITY, GeometricController


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """(n, 9) row-major rotations of (n, 4) unit quaternions (w, x, y, z), each entry written
    in place (no stack of nine temporaries)."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz, wx, wy, wz = x * y, x * z, y * z, w * x, w * y, w * z
    R = np.empty((len(q), 9))
    add, sub = np.add, np.subtract
    for k, op, a, b in (
        (1, sub, xy, wz), (2, add, xz, wy), (3, add, xy, wz),
        (5, sub, yz, wx), (6, sub, xz, wy), (7, add, yz, wx),
    ):  # fmt: skip
        col = op(a, b, out=R[:, k])
        col *= 2  # 2·(a ± b)
    for k, a, b in ((0, yy, zz), (4, xx, zz), (8, xx, yy)):
        col = add(a, b, out=R[:, k])
        col *= 2
        sub(1, col, out=col)  # 1 − 2·(a + b)
    return R


class References:
    """Per drone: a rest-to-rest minimum-jerk path (:class:`~.controller.MinJerk`), or the
    landing descent (min-jerk to a flare above the touchdown point, then a constant sink)."""

    def __init__(self, n: int, lead: float, land_duration: float, land_speed: float):
        self.start = np.zeros((n, 3))
        self.delta = np.zeros((n, 3))
        self.duration = np.ones(n)
        self.descent = np.zeros(n, dtype=bool)  # the sink phase after the min-jerk part
        self.end = np.zeros((n, 3))
        self.lead, self.land_duration, self.land_speed = lead, land_duration, land_speed

    def set(self, i, start, end, duration, descent) -> None:
        """Drones ``i`` (index array) follow a new path from ``start`` to ``end`` (n, 3)."""
        self.start[i] = start
        self.delta[i] = end - start
        self.duration[i] = duration
        self.descent[i] = descent
        self.end[i] = end

    def __call__(self, i, t: np.ndarray):
        """(position, velocity, acceleration) at times ``t`` of drones ``i``, (n, 3) each."""
        T, start, delta = self.duration[i], self.start[i], self.delta[i]
        ta = t + self.lead
        u = np.maximum(ta, 0.0) / T
        dds = np.where(ta >= T, 0.0, 60 * u * (1 - u) * (1 - 2 * u) / (T * T))
        u = np.maximum(t, 0.0) / T
        u2 = u * u
        s = u2 * u * (10 - 15 * u + 6 * u2)
        ds = 30 * u2 * (1 - u) ** 2 / T
        done = t >= T
        s, ds, dds = np.where(done, 1.0, s), np.where(done, 0.0, ds), np.where(done, 0.0, dds)
        p = start + s[:, None] * delta
        p = np.where(done[:, None], start + delta, p)  # the scalar path returns x + dx exactly
        v = ds[:, None] * delta
        a = dds[:, None] * delta
        sink = self.descent[i] & (t >= self.land_duration)
        if np.count_nonzero(sink):
            end = self.end[i]  # x, y over the touchdown point, z the flare
            z = end[:, 2] - self.land_speed * (t - self.land_duration)
            p = np.where(sink[:, None], np.stack([end[:, 0], end[:, 1], z], 1), p)
            v = np.where(sink[:, None], np.array([0.0, 0.0, -self.land_speed]), v)
            a = np.where(sink[:, None], 0.0, a)
        return p, v, a


class BatchedController:
    """:class:`~cpp_mujoco.physics.controller.GeometricController` for n drones: the gains
    are the scalar controller's (built from the same parameters), the state is per drone."""

    def __init__(self, scalar: GeometricController, n: int):
        self.c = scalar
        self.A_inv = np.array(scalar.A_inv)  # (4 rotors, [thrust, roll, pitch, yaw])
        self.integral = np.zeros((n, 3))
        self.disturbance = np.zeros((n, 3))
        self.last_vel = np.zeros((n, 3))
        self.last_force = np.zeros((n, 3))
        self.has_last = np.zeros(n, dtype=bool)

    def reset(self, i) -> None:
        self.integral[i] = 0.0
        self.disturbance[i] = 0.0
        self.has_last[i] = False

    def observe(self, i, vel, R, thrusts, dt: float) -> None:
        """:meth:`GeometricController.observe` for drones ``i``."""
        c = self.c
        total = thrusts[:, 0] + thrusts[:, 1] + thrusts[:, 2] + thrusts[:, 3]
        m = c.mass
        force = np.stack([total * R[:, 2], total * R[:, 5], total * R[:, 8] - m * GRAVITY], 1)
        had = self.has_last[i]
        v, g = self.last_vel[i], self.last_force[i]
        self.last_vel[i], self.last_force[i], self.has_last[i] = vel, force, True
        a, lim, d = dt / (c.obs_tau + dt), c.obs_limit, self.disturbance[i]
        k = m / dt
        d = d + a * (k * (vel - v) - 0.5 * (force + g) - d)
        norm2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
        over = norm2 > lim * lim
        if np.count_nonzero(over):
            d[over] *= (lim / np.sqrt(norm2[over]))[:, None]
        self.disturbance[i] = np.where(had[:, None], d, self.disturbance[i])

    def __call__(self, i, pos, vel, R, omega, ref_p, ref_v, ref_a, dt: float) -> np.ndarray:
        """(n, 4) rotor thrusts: :meth:`GeometricController.__call__` for drones ``i``."""
        c = self.c
        kx, kv, m, ki, lim = c.kx, c.kv, c.mass, c.ki * dt, c.i_limit
        e = pos - ref_p
        ig = self.integral[i] - ki * e
        n2 = ig[:, 0] * ig[:, 0] + ig[:, 1] * ig[:, 1] + ig[:, 2] * ig[:, 2]
        over = n2 > lim * lim
        if np.count_nonzero(over):
            ig[over] *= (lim / np.sqrt(n2[over]))[:, None]
        self.integral[i] = ig
        acc = ref_a + np.array([0.0, 0.0, GRAVITY])
        f = -kx * e - kv * (vel - ref_v) + ig + m * acc - self.disturbance[i]
        fx, fy, fz = f[:, 0], f[:, 1], np.maximum(f[:, 2], c.min_fz)
        horiz2 = fx * fx + fy * fy
        cap = fz * c.tan_tilt
        steep = horiz2 > cap * cap
        fz = np.where(steep, np.minimum(np.sqrt(horiz2) / c.tan_tilt, np.maximum(fz, c.weight)), fz)
        cap = fz * c.tan_tilt
        steep = horiz2 > cap * cap
        if np.count_nonzero(steep):
            scale = np.where(steep, cap / np.sqrt(np.where(steep, horiz2, 1.0)), 1.0)
            fx, fy = np.where(steep, fx * scale, fx), np.where(steep, fy * scale, fy)
            horiz2 = np.where(steep, cap * cap, horiz2)
        r0, r1, r2, r3, r4, r5, r6, r7, r8 = R.T
        thrust = fx * r2 + fy * r5 + fz * r8
        n = 1.0 / np.sqrt(horiz2 + fz * fz)
        a0, a1, a2 = fx * n, fy * n, fz * n
        nb = 1.0 / np.sqrt(a1 * a1 + a2 * a2)
        b1, b2 = a2 * nb, -a1 * nb
        c0, c1, c2 = b1 * a2 - b2 * a1, b2 * a0, -b1 * a0
        er0 = 0.5 * (a0 * r1 + a1 * r4 + a2 * r7 - (b1 * r5 + b2 * r8))
        er1 = 0.5 * (c0 * r2 + c1 * r5 + c2 * r8 - (a0 * r0 + a1 * r3 + a2 * r6))
        er2 = 0.5 * (b1 * r3 + b2 * r6 - (c0 * r1 + c1 * r4 + c2 * r7))
        w0, w1, w2 = omega[:, 0], omega[:, 1], omega[:, 2]
        jx, jy, jz = c.J
        (kR0, kR1, kR2), (kW0, kW1, kW2) = c.kR, c.kW
        mx = -kR0 * er0 - kW0 * w0 + (jz - jy) * w1 * w2
        my = -kR1 * er1 - kW1 * w1 + (jx - jz) * w2 * w0
        mz = -kR2 * er2 - kW2 * w2 + (jy - jx) * w0 * w1
        return self.mix(thrust, mx, my, mz)

    def mix(self, thrust, mx, my, mz) -> np.ndarray:
        """:meth:`GeometricController.mix` (yaw given up first, then collective, then roll and
        pitch scaled) for every drone."""
        fmax = self.c.f_max
        A = self.A_inv
        p = A[:, 1] * mx[:, None] + A[:, 2] * my[:, None]
        f = A[:, 0] * thrust[:, None] + p
        low, high = _row_min(f), _row_max(f)
        out = (low < 0.0) | (high > fmax)
        if np.count_nonzero(out):
            wide = out & (high - low > fmax)
            if np.count_nonzero(wide):
                k = np.where(wide, fmax / np.where(wide, high - low, 1.0), 1.0)
                p = np.where(wide[:, None], p * k[:, None], p)
                f = np.where(wide[:, None], A[:, 0] * thrust[:, None] + p, f)
                low, high = _row_min(f), _row_max(f)
            shift = np.where(low < 0.0, -low, np.where(high > fmax, fmax - high, 0.0))
            f = np.where(out[:, None], f + shift[:, None], f)
        yaw = A[:, 3] * mz[:, None]
        total = f + yaw
        with np.errstate(divide="ignore", invalid="ignore"):
            share = np.where(total > fmax, (fmax - f) / yaw, np.where(total < 0.0, -f / yaw, 1.0))
        s = np.minimum(_row_min(share), 1.0)
        partial = s < 1.0
        if not np.count_nonzero(partial):
            return total
        s = np.maximum(s, 0.0)
        clipped = np.minimum(fmax, np.maximum(0.0, f + s[:, None] * yaw))
        return np.where(partial[:, None], clipped, total)


def _row_min(a: np.ndarray) -> np.ndarray:
    """Each row's minimum of an (n, 4) array: ``a.min(1)`` (NaN included), in three calls that
    cost less than a reduction along a short axis."""
    return np.minimum(np.minimum(a[:, 0], a[:, 1]), np.minimum(a[:, 2], a[:, 3]))


def _row_max(a: np.ndarray) -> np.ndarray:
    """Each row's maximum of an (n, 4) array, as :func:`_row_min`."""
    return np.maximum(np.maximum(a[:, 0], a[:, 1]), np.maximum(a[:, 2], a[:, 3]))


def drag_force(half_rho_cda: float, vel: np.ndarray, wind: np.ndarray) -> np.ndarray:
    """:meth:`~cpp_mujoco.physics.wind.QuadraticDrag.force` for (n, 3) velocities and winds."""
    r = wind - vel
    k = half_rho_cda * np.sqrt(r[:, 0] * r[:, 0] + r[:, 1] * r[:, 1] + r[:, 2] * r[:, 2])
    return k[:, None] * r


def air_in_body(vel: np.ndarray, wind: np.ndarray, R: np.ndarray) -> np.ndarray:
    """:func:`~cpp_mujoco.physics.energy.air_in_body` for n drones: (n, 3) body-frame air."""
    v = vel - wind
    vx, vy, vz = v[:, 0], v[:, 1], v[:, 2]
    return np.stack(
        [
            R[:, 0] * vx + R[:, 3] * vy + R[:, 6] * vz,
            R[:, 1] * vx + R[:, 4] * vy + R[:, 7] * vz,
            R[:, 2] * vx + R[:, 5] * vy + R[:, 8] * vz,
        ],
        1,
    )
