"""The flight's control tick as numba kernels: the one implementation of the reference, the
controller, the wind and the drag.

Why compiled: as numpy, a tick is ≈ 150 calls, each microseconds of dispatch over a short array.
Compiled, the per-drone arithmetic is a loop over plain doubles in two calls: :func:`sense`
(rotation, failure checks, no-fly count, reference, tracking, camera and done checks) and
:func:`control` (wind, observer, controller, mixer, drag; then
:func:`~cpp_mujoco.physics.power.kernels.power`: energy, battery). No fastmath (exp, log, hypot
are the C library's). The kernels work on the state arrays of
:mod:`~cpp_mujoco.physics.control.controller` and :mod:`~cpp_mujoco.physics.air.wind`; what needs
Python is flagged in ``code`` for :mod:`~cpp_mujoco.physics.tick`. :func:`wind` and
:func:`thrusts` are the same rules as array parts (:mod:`~cpp_mujoco.physics.parts`). Run
uncompiled (``sense.py_func``) they are their own reference (``tests/test_compiled_tick.py``).
Constants come in arguments, none from another module's globals: numba freezes those into its
cache, which notices only this file's changes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# code & 7: why a drone's action ends this tick (0: it flies on); the bits above: flags
FLY, BROKEN, OUT, FLIPPED, DIVERGED, ARRIVED, TIMED_OUT, ENDED = range(8)
DUE, CHECK = 8, 16  # a camera frame is due; Python checks contacts and time limits
NEED_NOISE, NEED_COEFFICIENTS = -1, -2  # control(): nothing done, Python supplies these first

_SQRT3 = math.sqrt(3.0)


@njit(cache=True)
def sense(i, st, q0, v0, c, on, bad, bad0, no_fly, nfz, ncon, next_frame, start, delta,
          duration, descent, end, t, t0, goal, nominal, limit, arrive, land, worst2, flying,
          arrived, R, ref, code, lists):  # fmt: skip
    """The first half of a tick for drones ``i``: R (m, 9), the
    reference (m, 9: p, v, a) and ``code`` per drone; the drones whose action ends leave
    ``flying``. ``lists`` rows: the drones with a frame due, those flying on (but for a
    landing check), the positions in ``i`` to check. Returns (failed, due, go, check) counts."""
    bx, by, bz, cos_flip, height, width, inv, k = c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]
    lead, land_t, sink_v, max_err2, pos_tol2 = c[8], c[9], c[10], c[11], c[12]
    vel_tol2, fall_limit, ticks = c[13], c[14], int(k)
    failed = due = go = check = 0
    for j in range(i.size):
        d = i[j]
        x, y, z = st[d, q0], st[d, q0 + 1], st[d, q0 + 2]
        w, qx, qy, qz = st[d, q0 + 3], st[d, q0 + 4], st[d, q0 + 5], st[d, q0 + 6]
        xx, yy, zz = qx * qx, qy * qy, qz * qz
        xy, xz, yz, wx, wy, wz = qx * qy, qx * qz, qy * qz, w * qx, w * qy, w * qz
        r = R[j]
        r[0], r[1], r[2] = 1 - (yy + zz) * 2, (xy - wz) * 2, (xz + wy) * 2
        r[3], r[4], r[5] = (xy + wz) * 2, 1 - (xx + zz) * 2, (yz - wx) * 2
        r[6], r[7], r[8] = (xz - wy) * 2, (yz + wx) * 2, 1 - (xx + yy) * 2
        # ---- failure checks on the current state
        broken = not math.isfinite(x + y + z + w + qx + qy + qz) or bad[d] != bad0[d]
        out = abs(x) > bx or abs(y) > by or z > bz
        flipped = r[8] < cos_flip and on[d]
        row = np.floor(height / 2 - y * inv)
        col = np.floor(x * inv + width / 2)
        inside = row >= 0 and row < height and col >= 0 and col < width
        if not inside or no_fly[int(row * width + col)]:
            nfz[d] += ticks
        # ---- the reference (References.__call__)
        td, T = t[d], duration[d]
        ta = td + lead
        u = max(ta, 0.0) / T
        dds = 0.0 if ta >= T else 60 * u * (1 - u) * (1 - 2 * u) / (T * T)
        u = max(td, 0.0) / T
        u2 = u * u
        s = u2 * u * (10 - 15 * u + 6 * u2)
        ds = 30 * u2 * (1 - u) ** 2 / T
        done = td >= T
        if done:
            s, ds, dds = 1.0, 0.0, 0.0
        p = ref[j]
        for a in range(3):
            p[a] = start[d, a] + delta[d, a] if done else start[d, a] + s * delta[d, a]
            p[3 + a] = ds * delta[d, a]
            p[6 + a] = dds * delta[d, a]
        if descent[d] and td >= land_t:  # the constant sink over the touchdown point
            p[0], p[1], p[2] = end[d, 0], end[d, 1], end[d, 2] - sink_v * (td - land_t)
            p[3], p[4], p[5], p[6], p[7], p[8] = 0.0, 0.0, -sink_v, 0.0, 0.0, 0.0
        ex, ey, ez = x - p[0], y - p[1], z - p[2]
        kind = BROKEN if broken else OUT if out else FLIPPED if flipped else FLY
        if kind == FLY and on[d]:
            off2 = ex * ex + ey * ey
            if off2 > worst2[d]:
                worst2[d] = off2
            if off2 + ez * ez > max_err2:
                kind = DIVERGED
        if kind != FLY:
            failed += 1
            code[j], flying[d] = kind, False
            continue
        # ---- camera frame due, then: is the action done?
        flags = DUE if t0[d] + td >= next_frame[d] else 0
        if not on[d] or land[d]:  # Python looks only where a contact or a limit may end it
            if ncon[d] > 0 or td >= (limit[d] if on[d] else fall_limit):
                flags |= CHECK
        elif td >= nominal[d]:
            gx, gy, gz = x - goal[d, 0], y - goal[d, 1], z - goal[d, 2]
            vx, vy, vz = st[d, v0], st[d, v0 + 1], st[d, v0 + 2]
            near = gx * gx + gy * gy + gz * gz < pos_tol2
            slow = vx * vx + vy * vy + vz * vz < vel_tol2
            if arrive[d] and near and slow:
                kind = ARRIVED
            elif td >= limit[d] - 1e-9:
                kind = TIMED_OUT
        code[j] = kind | flags
        if kind == FLY:
            lists[1, go] = d
            go += 1
        else:
            flying[d] = False
            arrived[d] |= kind == ARRIVED
        if flags & DUE:
            lists[0, due] = d
            due += 1
        if flags & CHECK:
            lists[2, check] = j
            check += 1
    return failed, due, go, check


@njit(cache=True)
def _observe(d, vx, vy, vz, r, act, c, disturbance, last_vel, last_force, has_last):
    """The disturbance observer of drone ``d``: what accelerated the body beyond the rotors'
    actual thrust and gravity, low-pass filtered and bounded."""
    dt, m, obs_tau, lim = c[5], c[8], c[15], c[16]
    total = act[0] + act[1] + act[2] + act[3]
    f0, f1, f2 = total * r[2], total * r[5], total * r[8] - m * c[3]
    if has_last[d]:
        a, k = dt / (obs_tau + dt), m / dt
        d0, d1, d2 = disturbance[d, 0], disturbance[d, 1], disturbance[d, 2]
        d0 += a * (k * (vx - last_vel[d, 0]) - 0.5 * (f0 + last_force[d, 0]) - d0)
        d1 += a * (k * (vy - last_vel[d, 1]) - 0.5 * (f1 + last_force[d, 1]) - d1)
        d2 += a * (k * (vz - last_vel[d, 2]) - 0.5 * (f2 + last_force[d, 2]) - d2)
        if d0 * d0 + d1 * d1 + d2 * d2 > lim * lim:
            scale = lim / math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            d0, d1, d2 = d0 * scale, d1 * scale, d2 * scale
        disturbance[d, 0], disturbance[d, 1], disturbance[d, 2] = d0, d1, d2
    last_vel[d, 0], last_vel[d, 1], last_vel[d, 2] = vx, vy, vz
    last_force[d, 0], last_force[d, 1], last_force[d, 2] = f0, f1, f2
    has_last[d] = True


@njit(cache=True)
def _thrusts(d, pos, vel, r, omega, p, c, integral, disturbance, A, f):
    """The geometric law and the mixer for drone ``d``: rotor thrusts in ``f[:4]`` (``f[4:]``
    scratch); ``p``: the reference (p, v, a). Force: PID on position (anti-windup bound) plus
    feedforward minus the observed disturbance, tilt limited (sink rate given up first); then
    b3d along the force, b1d towards yaw 0, e_R = ½ vee(Rdᵀ R − Rᵀ Rd), M = −k_R e_R − k_Ω Ω +
    Ω × JΩ."""
    kx, kv, m, ki, lim, tan_tilt, min_fz = c[6], c[7], c[8], c[9], c[10], c[11], c[12]
    weight, fmax, jx, jy, jz = c[13], c[14], c[17], c[18], c[19]
    kR0, kR1, kR2, kW0, kW1, kW2 = c[20], c[21], c[22], c[23], c[24], c[25]
    ex, ey, ez = pos[0] - p[0], pos[1] - p[1], pos[2] - p[2]
    ix, iy, iz = integral[d, 0] - ki * ex, integral[d, 1] - ki * ey, integral[d, 2] - ki * ez
    if ix * ix + iy * iy + iz * iz > lim * lim:  # anti-windup: bound the integral force
        k = lim / math.sqrt(ix * ix + iy * iy + iz * iz)
        ix, iy, iz = ix * k, iy * k, iz * k
    integral[d, 0], integral[d, 1], integral[d, 2] = ix, iy, iz
    dx, dy, dz = disturbance[d, 0], disturbance[d, 1], disturbance[d, 2]
    fx = -kx * ex - kv * (vel[0] - p[3]) + ix + m * p[6] - dx
    fy = -kx * ey - kv * (vel[1] - p[4]) + iy + m * p[7] - dy
    fz = -kx * ez - kv * (vel[2] - p[5]) + iz + m * (p[8] + c[3]) - dz
    if fz < min_fz:
        fz = min_fz
    horiz2 = fx * fx + fy * fy
    cap = fz * tan_tilt
    if horiz2 > cap * cap:
        fz = min(math.sqrt(horiz2) / tan_tilt, max(fz, weight))
        cap = fz * tan_tilt
    if horiz2 > cap * cap:
        scale = cap / math.sqrt(horiz2)
        fx, fy = fx * scale, fy * scale
        horiz2 = cap * cap
    r0, r1, r2, r3, r4, r5, r6, r7, r8 = r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]
    thrust = fx * r2 + fy * r5 + fz * r8
    n = 1.0 / math.sqrt(horiz2 + fz * fz)
    a0, a1, a2 = fx * n, fy * n, fz * n
    nb = 1.0 / math.sqrt(a1 * a1 + a2 * a2)
    b1, b2 = a2 * nb, -a1 * nb
    c0, c1, c2 = b1 * a2 - b2 * a1, b2 * a0, -b1 * a0
    er0 = 0.5 * (a0 * r1 + a1 * r4 + a2 * r7 - (b1 * r5 + b2 * r8))
    er1 = 0.5 * (c0 * r2 + c1 * r5 + c2 * r8 - (a0 * r0 + a1 * r3 + a2 * r6))
    er2 = 0.5 * (b1 * r3 + b2 * r6 - (c0 * r1 + c1 * r4 + c2 * r7))
    w0, w1, w2 = omega[0], omega[1], omega[2]
    mx = -kR0 * er0 - kW0 * w0 + (jz - jy) * w1 * w2
    my = -kR1 * er1 - kW1 * w1 + (jx - jz) * w2 * w0
    mz = -kR2 * er2 - kW2 * w2 + (jy - jx) * w0 * w1
    # ---- mix: yaw given up first, then collective, then roll and pitch scaled
    pr = f[4:]
    for k in range(4):
        pr[k] = A[k, 1] * mx + A[k, 2] * my
        f[k] = A[k, 0] * thrust + pr[k]
    low, high = min(f[0], f[1], f[2], f[3]), max(f[0], f[1], f[2], f[3])
    if low < 0.0 or high > fmax:
        if high - low > fmax:
            k = fmax / (high - low)
            for a in range(4):
                pr[a] = pr[a] * k
                f[a] = A[a, 0] * thrust + pr[a]
            low, high = min(f[0], f[1], f[2], f[3]), max(f[0], f[1], f[2], f[3])
        shift = -low if low < 0.0 else (fmax - high if high > fmax else 0.0)
        for a in range(4):
            f[a] = f[a] + shift
    s = 1.0
    for a in range(4):
        y = A[a, 3] * mz
        if f[a] + y > fmax:
            s = min(s, (fmax - f[a]) / y)
        elif f[a] + y < 0.0:
            s = min(s, -f[a] / y)
    if s == 1.0:
        for a in range(4):
            f[a] = f[a] + A[a, 3] * mz
        return
    s = max(s, 0.0)
    for a in range(4):
        f[a] = min(fmax, max(0.0, f[a] + s * (A[a, 3] * mz)))


@njit(cache=True)
def _mean_wind(d, x, y, z, c, steady, gust, gust_block, gust_left, last, has_last):
    """(g0, g1, w0, w1, w2, airspeed): the gusts after this tick's kick (the noise only
    peeked: nothing stored), the steady wind plus them, and the air's speed past the drone
    (the turbulence's time scales)."""
    w0, w1, w2 = steady[d, 0], steady[d, 1], steady[d, 2]
    g0 = g1 = 0.0
    if c[0]:
        n = gust_left[d]
        g0 = gust[d, 0] * c[1] + c[2] * gust_block[d, n - 1]
        g1 = gust[d, 1] * c[1] + c[2] * gust_block[d, n - 2]
        w0, w1 = w0 + g0, w1 + g1
    rx, ry, rz = w0, w1, w2
    if has_last[d]:
        k = 1.0 / c[4]
        rx, ry, rz = rx - (x - last[d, 0]) * k, ry - (y - last[d, 1]) * k, rz - (z - last[d, 2]) * k
    return g0, g1, w0, w1, w2, math.sqrt(rx * rx + ry * ry + rz * rz)


@njit(cache=True)
def _wind_ready(i, mask, pos, c, steady, gust, gust_block, gust_left, turb_left, last, has_last,
                filled, keys):  # fmt: skip
    """0 when every drone ``i[j]`` with ``mask[j]`` has the normals and the turbulence
    coefficients its wind needs this tick (their table keys written into ``keys``), else
    NEED_NOISE or NEED_COEFFICIENTS. ``pos[j]``: drone ``i[j]``'s position."""
    gusty, turbulent, min_air, per_log, max_keys = c[0] != 0.0, c[34] != 0.0, c[35], c[36], c[-1]
    missing = 0
    for j in range(i.size):
        if mask[j]:
            d = i[j]
            missing += (gusty and gust_left[d] < 2) or (turbulent and turb_left[d] < 5)
    if missing:
        return NEED_NOISE
    for j in range(i.size):
        if turbulent and mask[j]:
            speed = _mean_wind(i[j], pos[j, 0], pos[j, 1], pos[j, 2], c, steady, gust,
                               gust_block, gust_left, last, has_last)[5]  # fmt: skip
            key = np.rint(math.log(max(speed, min_air)) * per_log)
            if not 0.0 <= key < max_keys:
                key = -1.0  # diverged: no table row, the turbulence turns NaN
            keys[j] = key
            missing += key >= 0.0 and (key >= filled.size or not filled[int(key)])
    return NEED_COEFFICIENTS if missing else 0


@njit(cache=True)
def dryden_step(tc, s, noise, n):
    """Dryden turbulence one tick on: the filter states ``s`` (u; v, v'; w, w') advanced with
    the tick's coefficients ``tc`` and the normals ``noise[n-1]`` … ``noise[n-5]``; returns the
    unscaled outputs (u, v1 + √3·v2, w1 + √3·w2)."""
    u = tc[0] * s[0] + tc[1] * noise[n - 1]
    a, b = noise[n - 2], noise[n - 3]
    v1 = tc[2] * s[1] + tc[3] * s[2] + tc[6] * a
    v2 = tc[4] * s[1] + tc[5] * s[2] + tc[7] * a + tc[8] * b
    a, b = noise[n - 4], noise[n - 5]
    z1 = tc[9] * s[3] + tc[10] * s[4] + tc[13] * a
    z2 = tc[11] * s[3] + tc[12] * s[4] + tc[14] * a + tc[15] * b
    s[0], s[1], s[2], s[3], s[4] = u, v1, v2, z1, z2
    return u, v1 + _SQRT3 * v2, z1 + _SQRT3 * z2


@njit(cache=True)
def _wind_at(d, key, x, y, z, c, steady, axis, gust, gust_block, gust_left, turb, turb_block,
             turb_left, last, has_last, table):  # fmt: skip
    """The wind drone ``d`` at (x, y, z) flies in this tick (steady + gusts + turbulence),
    its gusts and turbulence advanced; ``key``: its turbulence table row (−1: NaN)."""
    g0, g1, w0, w1, w2, _ = _mean_wind(d, x, y, z, c, steady, gust, gust_block, gust_left,
                                       last, has_last)  # fmt: skip
    if c[0] != 0.0:
        gust[d, 0], gust[d, 1] = g0, g1
        gust_left[d] -= 2
    if c[34] != 0.0:
        last[d, 0], last[d, 1], last[d, 2], has_last[d] = x, y, z, True
        tc = table[int(key)] if key >= 0.0 else np.full(16, np.nan)
        n = turb_left[d]
        turb_left[d] = n - 5
        u, v, w = dryden_step(tc, turb[d], turb_block[d], n)
        gust_u, gust_v, gust_w = c[37] * u, c[38] * v, c[39] * w
        cx, cy = axis[d, 0], axis[d, 1]
        w0, w1, w2 = w0 + gust_u * cx - gust_v * cy, w1 + gust_u * cy + gust_v * cx, w2 + gust_w
    return w0, w1, w2


@njit(cache=True)
def wind(i, pos, c, steady, axis, gust, gust_block, gust_left, turb, turb_block, turb_left,
         last, has_last, table, filled, keys, out):  # fmt: skip
    """The wind of drones ``i`` at ``pos`` (m, 3) this tick into ``out`` (m, 3): the default
    wind part's :meth:`~cpp_mujoco.physics.air.wind.Wind.velocity`. Returns 0, or
    NEED_NOISE / NEED_COEFFICIENTS having changed nothing."""
    need = _wind_ready(i, np.ones(i.size, dtype=np.bool_), pos, c, steady, gust, gust_block,
                       gust_left, turb_left, last, has_last, filled, keys)  # fmt: skip
    if need:
        return need
    for j in range(i.size):
        out[j, 0], out[j, 1], out[j, 2] = _wind_at(
            i[j], keys[j], pos[j, 0], pos[j, 1], pos[j, 2], c, steady, axis, gust, gust_block,
            gust_left, turb, turb_block, turb_left, last, has_last, table,
        )  # fmt: skip
    return 0


@njit(cache=True)
def thrusts(i, pos, vel, R, omega, act, ref, c, A, integral, disturbance, last_vel, last_force,
            has_last, out):  # fmt: skip
    """The built-in controller as an array part: observer, geometric law and mixer for drones
    ``i`` (row j of each array: drone ``i[j]``'s position, velocity, rotation (9), body rates,
    rotor thrusts (4) and reference (9: p, v, a)); rotor thrusts into ``out`` (m, 4)."""
    f = np.empty(8)
    for j in range(i.size):
        d = i[j]
        _observe(d, vel[j, 0], vel[j, 1], vel[j, 2], R[j], act[j], c, disturbance, last_vel,
                 last_force, has_last)  # fmt: skip
        _thrusts(d, pos[j], vel[j], R[j], omega[j], ref[j], c, integral, disturbance, A, f)
        out[j, :] = f[:4]


@njit(cache=True)
def control(i, code, st, cols, c, R, ref, motors_on, A, integral, disturbance, last_vel,
            last_force, has_last, steady, axis, gust, gust_block, gust_left, turb, turb_block,
            turb_left, last, has_last_pos, table, filled, keys, air, wind_now, given):  # fmt: skip
    """The wind, observer, controller and drag of a tick for the drones of ``i`` whose
    ``code`` is FLY: ctrl and drag force written into their state rows, the air in the body
    frame into ``air`` (row k: the k-th of them), for ``power.kernels.power``, and the wind
    they fly in into ``wind_now`` (per drone). ``given``: 1 the wind, 2 the thrusts, 3 both,
    are a user part's, already in ``wind_now`` / the ctrl rows. Returns 0, or NEED_NOISE /
    NEED_COEFFICIENTS (``keys`` written) having changed nothing. ``c``:
    :func:`~cpp_mujoco.physics.kernel_constants.control_constants`."""
    q0, v0, a0, u0, x0 = cols[0], cols[1], cols[2], cols[3], cols[4]
    half_rho_cda = c[33]
    own_wind, own_thrust = given & 1 == 0, given & 2 == 0
    fly = np.empty(i.size, dtype=np.bool_)
    pos = np.empty((i.size, 3))
    for j in range(i.size):
        fly[j] = code[j] & 7 == FLY
        pos[j] = st[i[j], q0 : q0 + 3]
    if own_wind:
        need = _wind_ready(i, fly, pos, c, steady, gust, gust_block, gust_left, turb_left, last,
                           has_last_pos, filled, keys)  # fmt: skip
        if need:
            return need
    f = np.empty(8)
    k = 0
    for j in range(i.size):
        if not fly[j]:
            continue
        d = i[j]
        vel, r = st[d, v0 : v0 + 3], R[j]
        if own_wind:
            w0, w1, w2 = _wind_at(d, keys[j], pos[j, 0], pos[j, 1], pos[j, 2], c, steady, axis,
                                  gust, gust_block, gust_left, turb, turb_block, turb_left, last,
                                  has_last_pos, table)  # fmt: skip
            wind_now[d, 0], wind_now[d, 1], wind_now[d, 2] = w0, w1, w2
        else:
            w0, w1, w2 = wind_now[d, 0], wind_now[d, 1], wind_now[d, 2]
        if motors_on[d]:
            if own_thrust:
                act = st[d, a0 : a0 + 4]
                _observe(d, vel[0], vel[1], vel[2], r, act, c, disturbance, last_vel, last_force,
                         has_last)  # fmt: skip
                _thrusts(d, pos[j], vel, r, st[d, v0 + 3 : v0 + 6], ref[j], c, integral,
                         disturbance, A, f)  # fmt: skip
                st[d, u0 : u0 + 4] = f[:4]
            bx, by, bz = vel[0] - w0, vel[1] - w1, vel[2] - w2
            air[k, 0] = r[0] * bx + r[3] * by + r[6] * bz
            air[k, 1] = r[1] * bx + r[4] * by + r[7] * bz
            air[k, 2] = r[2] * bx + r[5] * by + r[8] * bz
        else:
            st[d, u0 : u0 + 4] = 0.0
        k += 1
        rx, ry, rz = w0 - vel[0], w1 - vel[1], w2 - vel[2]
        kd = half_rho_cda * math.sqrt(rx * rx + ry * ry + rz * rz)
        st[d, x0], st[d, x0 + 1], st[d, x0 + 2] = kd * rx, kd * ry, kd * rz
    return 0
