"""Waypoint tracking: a minimum-jerk reference and a geometric SE(3) controller (Lee et al. 2010).

Why geometric rather than cascaded PID: it works on the rotation matrix directly, so it has no
Euler-angle singularities and the thrust direction and attitude errors are exact for any tilt; the
whole law is a few dozen multiply-adds, cheap enough in plain Python floats (numpy on 3-vectors
costs a microsecond per call and would dominate the physics step).

Chain: position/velocity error → desired force (minus the observed external force) → desired
attitude (thrust axis along the force, heading fixed) → torque from attitude and body-rate errors
→ rotor thrusts through the inverse allocation matrix, with saturation priority
roll/pitch > collective thrust > yaw.
"""

from __future__ import annotations

import math

import numpy as np

from cpp_mujoco.physics.config import ControllerGains
from cpp_mujoco.physics.quadrotor import QuadrotorParams

GRAVITY = 9.81


class MinJerk:
    """Rest-to-rest minimum-jerk path from ``start`` to ``end`` over ``duration`` seconds.

    The acceleration is returned ``lead`` seconds ahead: the airframe realises a commanded
    acceleration only after the attitude loop and the rotor lag (≈ 0.1 s), and feeding it forward
    that much early removes the tracking lag and the overshoot it would cause at arrival.
    """

    __slots__ = ("start", "delta", "duration", "lead")

    def __init__(self, start, end, duration: float, lead: float = 0.0):
        self.start = tuple(float(v) for v in start)
        self.delta = tuple(float(e) - s for s, e in zip(self.start, end, strict=True))
        self.duration = float(duration)
        self.lead = float(lead)

    def __call__(self, t: float):
        """(position, velocity, acceleration at t + lead); held at the end after ``duration``."""
        T = self.duration
        (x, y, z), (dx, dy, dz) = self.start, self.delta
        ta = t + self.lead
        if ta >= T:
            dds = 0.0
        else:
            u = max(ta, 0.0) / T
            dds = 60 * u * (1 - u) * (1 - 2 * u) / (T * T)
        if t >= T:
            return (x + dx, y + dy, z + dz), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        u = max(t, 0.0) / T
        u2 = u * u
        s = u2 * u * (10 - 15 * u + 6 * u2)
        ds = 30 * u2 * (1 - u) ** 2 / T
        return (
            (x + s * dx, y + s * dy, z + s * dz),
            (ds * dx, ds * dy, ds * dz),
            (dds * dx, dds * dy, dds * dz),
        )


class GeometricController:
    """Lee, Leok & McClamroch (2010) on SE(3), in plain floats. Heading held at yaw 0.

    The flight's default :class:`~cpp_mujoco.physics.parts.Controller` part; ``gains`` default
    to ``ControllerGains()`` (``PhysicsConfig.controller``).
    """

    def __init__(self, params: QuadrotorParams, gains: ControllerGains | None = None):
        g = gains if gains is not None else ControllerGains()
        self.gains = g
        m = params.mass
        self.mass = m
        self.kx = m * g.position_bw**2
        self.kv = 2 * g.position_damping * g.position_bw * m
        self.ki = self.kx * g.position_integral
        self.i_limit = g.integral_limit
        self.tan_tilt = math.tan(math.radians(g.tilt_limit_deg))
        jx, jy, jz = params.inertia
        self.J = (jx, jy, jz)
        self.kR = (jx * g.attitude_bw**2, jy * g.attitude_bw**2, jz * g.yaw_bw**2)
        self.kW = (
            2 * g.attitude_damping * g.attitude_bw * jx,
            2 * g.attitude_damping * g.attitude_bw * jy,
            2 * g.attitude_damping * g.yaw_bw * jz,
        )
        A = params.allocation_matrix()
        self.A = A
        self.A_inv = tuple(tuple(float(v) for v in row) for row in np.linalg.inv(A))
        self.f_max = params.max_thrust
        self.min_fz = 0.1 * m * GRAVITY
        self.weight = m * GRAVITY
        self.integral = (0.0, 0.0, 0.0)
        self.obs_tau, self.obs_limit = g.observer_tau, g.observer_limit
        self.lead = g.feedforward_lead
        self.reset()

    def reset(self) -> None:
        self.integral = (0.0, 0.0, 0.0)
        self.disturbance = (0.0, 0.0, 0.0)  # estimated external force (drag, wind), N
        self._last = None  # (velocity, rotor thrust force) at the previous update

    def observe(self, vel, R, thrusts, dt: float) -> None:
        """Update the external-force estimate: what accelerated the body beyond the rotors'
        actual thrust (``data.act``, i.e. measured rotor speed) and gravity, low-pass filtered.

        This is how a steady wind is rejected without an integrator's windup during moves.
        """
        total = thrusts[0] + thrusts[1] + thrusts[2] + thrusts[3]
        m = self.mass
        f0, f1, f2 = total * R[2], total * R[5], total * R[8] - m * GRAVITY
        last, self._last = self._last, (vel, f0, f1, f2)
        if last is None:
            return
        v, g0, g1, g2 = last
        a, lim, (d0, d1, d2) = dt / (self.obs_tau + dt), self.obs_limit, self.disturbance
        k = m / dt
        d0 += a * (k * (vel[0] - v[0]) - 0.5 * (f0 + g0) - d0)
        d1 += a * (k * (vel[1] - v[1]) - 0.5 * (f1 + g1) - d1)
        d2 += a * (k * (vel[2] - v[2]) - 0.5 * (f2 + g2) - d2)
        if d0 * d0 + d1 * d1 + d2 * d2 > lim * lim:
            scale = lim / math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            d0, d1, d2 = d0 * scale, d1 * scale, d2 * scale
        self.disturbance = (d0, d1, d2)

    def hover_thrust(self) -> float:
        """Per-rotor thrust that holds the weight."""
        return self.mass * GRAVITY / 4

    def __call__(self, pos, vel, R, omega, ref_p, ref_v, ref_a, dt: float) -> list[float]:
        """Rotor thrusts (N) for state (world position, world velocity, body→world rotation as a
        row-major 9-sequence, body angular velocity) and the reference (p, v, a).

        Written out in scalars on purpose: this runs at the control rate in Python.
        """
        kx, kv, m, ki, lim = self.kx, self.kv, self.mass, self.ki * dt, self.i_limit
        ig = self.integral
        ex, ey, ez = pos[0] - ref_p[0], pos[1] - ref_p[1], pos[2] - ref_p[2]
        ix, iy, iz = ig[0] - ki * ex, ig[1] - ki * ey, ig[2] - ki * ez
        if ix * ix + iy * iy + iz * iz > lim * lim:  # anti-windup: bound the integral force
            k = lim / math.sqrt(ix * ix + iy * iy + iz * iz)
            ix, iy, iz = ix * k, iy * k, iz * k
        self.integral = (ix, iy, iz)
        dx, dy, dz = self.disturbance
        fx = -kx * ex - kv * (vel[0] - ref_v[0]) + ix + m * ref_a[0] - dx
        fy = -kx * ey - kv * (vel[1] - ref_v[1]) + iy + m * ref_a[1] - dy
        fz = -kx * ez - kv * (vel[2] - ref_v[2]) + iz + m * (ref_a[2] + GRAVITY) - dz
        if fz < self.min_fz:  # never ask to push downwards
            fz = self.min_fz
        horiz2 = fx * fx + fy * fy
        cap = fz * self.tan_tilt
        if horiz2 > cap * cap:
            # a sinking reference leaves little thrust to tilt: give up sink rate first (never
            # lifting more than the weight), as holding the track beats descending fast
            fz = min(math.sqrt(horiz2) / self.tan_tilt, max(fz, self.weight))
            cap = fz * self.tan_tilt
        if horiz2 > cap * cap:  # limit the tilt, keep the vertical component
            scale = cap / math.sqrt(horiz2)
            fx, fy = fx * scale, fy * scale
            horiz2 = cap * cap
        r0, r1, r2, r3, r4, r5, r6, r7, r8 = R
        # collective thrust: the desired force projected on the current thrust axis b3 = R[:, 2]
        thrust = fx * r2 + fy * r5 + fz * r8
        # desired attitude: b3d along the force, b1d towards yaw 0 (east):
        # b2d = b3d × (1, 0, 0) normalised, b1d = b2d × b3d
        n = 1.0 / math.sqrt(horiz2 + fz * fz)
        a0, a1, a2 = fx * n, fy * n, fz * n
        nb = 1.0 / math.sqrt(a1 * a1 + a2 * a2)
        b1, b2 = a2 * nb, -a1 * nb  # b2d = (0, b1, b2)
        c0, c1, c2 = b1 * a2 - b2 * a1, b2 * a0, -b1 * a0  # b1d
        # e_R = ½ vee(Rdᵀ R − Rᵀ Rd), with R's columns (r0, r3, r6), (r1, r4, r7), (r2, r5, r8)
        er0 = 0.5 * (a0 * r1 + a1 * r4 + a2 * r7 - (b1 * r5 + b2 * r8))
        er1 = 0.5 * (c0 * r2 + c1 * r5 + c2 * r8 - (a0 * r0 + a1 * r3 + a2 * r6))
        er2 = 0.5 * (b1 * r3 + b2 * r6 - (c0 * r1 + c1 * r4 + c2 * r7))
        w0, w1, w2 = omega
        jx, jy, jz = self.J
        kR0, kR1, kR2 = self.kR
        kW0, kW1, kW2 = self.kW
        # M = −k_R e_R − k_Ω Ω + Ω × JΩ
        mx = -kR0 * er0 - kW0 * w0 + (jz - jy) * w1 * w2
        my = -kR1 * er1 - kW1 * w1 + (jx - jz) * w2 * w0
        mz = -kR2 * er2 - kW2 * w2 + (jy - jx) * w0 * w1
        return self.mix(thrust, mx, my, mz)

    def mix(self, thrust: float, mx: float, my: float, mz: float) -> list[float]:
        """Rotor thrusts in [0, f_max] for the wrench. Saturation gives up yaw first, then
        collective thrust, then (scaling) roll/pitch — a quadrotor that loses its attitude
        loses everything else too."""
        fmax = self.f_max
        (t0, x0, y0, z0), (t1, x1, y1, z1), (t2, x2, y2, z2), (t3, x3, y3, z3) = self.A_inv
        p0, p1, p2, p3 = x0 * mx + y0 * my, x1 * mx + y1 * my, x2 * mx + y2 * my, x3 * mx + y3 * my
        f0, f1, f2, f3 = t0 * thrust + p0, t1 * thrust + p1, t2 * thrust + p2, t3 * thrust + p3
        low, high = min(f0, f1, f2, f3), max(f0, f1, f2, f3)
        if low < 0.0 or high > fmax:
            if high - low > fmax:  # roll/pitch alone exceed the range: scale them down
                k = fmax / (high - low)
                p0, p1, p2, p3 = p0 * k, p1 * k, p2 * k, p3 * k
                f0, f1, f2, f3 = (
                    t0 * thrust + p0,
                    t1 * thrust + p1,
                    t2 * thrust + p2,
                    t3 * thrust + p3,
                )
                low, high = min(f0, f1, f2, f3), max(f0, f1, f2, f3)
            # shift the collective (equal on all rotors) just enough to fit
            shift = -low if low < 0.0 else (fmax - high if high > fmax else 0.0)
            f0, f1, f2, f3 = f0 + shift, f1 + shift, f2 + shift, f3 + shift
        f = [f0, f1, f2, f3]
        yaw = (z0 * mz, z1 * mz, z2 * mz, z3 * mz)
        s = 1.0  # the largest share of the yaw torque that still fits
        for v, y in zip(f, yaw):  # noqa: B905 - both have four entries
            if v + y > fmax:
                s = min(s, (fmax - v) / y)
            elif v + y < 0.0:
                s = min(s, -v / y)
        if s == 1.0:
            return [f0 + yaw[0], f1 + yaw[1], f2 + yaw[2], f3 + yaw[3]]
        s = max(s, 0.0)
        return [min(fmax, max(0.0, v + s * y)) for v, y in zip(f, yaw)]  # noqa: B905
