"""Waypoint tracking: a minimum-jerk reference and a geometric SE(3) controller (Lee et al. 2010).

Why geometric rather than cascaded PID: it works on the rotation matrix directly, so it has no
Euler-angle singularities and the thrust direction and attitude errors are exact for any tilt.

Chain: position/velocity error → desired force (minus the observed external force) → desired
attitude (thrust axis along the force, heading fixed) → torque from attitude and body-rate errors
→ rotor thrusts through the inverse allocation matrix, with saturation priority
roll/pitch > collective thrust > yaw. The law runs in the flight's compiled tick
(:func:`cpp_mujoco.physics.tick_kernels.control`); this module holds its gains and its state
per drone, and the reference each drone follows.
"""

from __future__ import annotations

import math

import numpy as np

from cpp_mujoco.physics import tick_kernels as kernels
from cpp_mujoco.physics.config import ControllerGains
from cpp_mujoco.physics.kernel_constants import GRAVITY, control_constants
from cpp_mujoco.physics.quadrotor import QuadrotorParams


class References:
    """Per drone: a rest-to-rest minimum-jerk path (position s(u) = 10u³ − 15u⁴ + 6u⁵ of the
    way), or the landing descent (min-jerk to a flare above the touchdown point, then a constant
    sink). The acceleration is taken ``lead`` s ahead: the airframe realises a commanded
    acceleration only after the attitude loop and the rotor lag (≈ 0.1 s), and feeding it
    forward that much early removes the tracking lag and the overshoot at arrival. The compiled
    ``sense`` evaluates it each tick."""

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


class GeometricController:
    """Lee, Leok & McClamroch (2010) on SE(3) for ``n`` drones, heading held at yaw 0: the gains
    (from the airframe's mass and inertia and ``gains``, default ``ControllerGains()``), the
    mixer, and per drone the integral, the disturbance observer's estimate and its last sample.

    The observer: what accelerated the body beyond the rotors' actual thrust (``data.act``,
    the measured rotor speed) and gravity, low-pass filtered — how a steady wind is rejected
    without an integrator's windup during moves."""

    def __init__(self, params: QuadrotorParams, gains: ControllerGains | None, n: int = 1):
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
        # (4 rotors, [thrust, roll, pitch, yaw]): wrench → rotor thrusts
        self.A_inv = np.ascontiguousarray(np.linalg.inv(params.allocation_matrix()))
        self.f_max = params.max_thrust
        self.min_fz = 0.1 * m * GRAVITY  # never ask to push downwards
        self.weight = m * GRAVITY
        self.obs_tau, self.obs_limit = g.observer_tau, g.observer_limit
        self.lead = g.feedforward_lead
        self.integral = np.zeros((n, 3))
        self.disturbance = np.zeros((n, 3))  # estimated external force (drag, wind), N
        self.last_vel = np.zeros((n, 3))
        self.last_force = np.zeros((n, 3))
        self.has_last = np.zeros(n, dtype=bool)
        self._constants: tuple | None = None  # (dt, the kernels' constants) of __call__

    def hover_thrust(self) -> float:
        """Per-rotor thrust that holds the weight: what an episode starts with."""
        return self.mass * GRAVITY / 4

    def reset(self, i) -> None:
        """Drones ``i`` start an episode: integral and observer forgotten."""
        self.integral[i] = 0.0
        self.disturbance[i] = 0.0
        self.has_last[i] = False

    def constants(self, dt: float) -> list[float]:
        """The gains as the compiled tick reads them (``control_constants``' order)."""
        return [
            self.kx, self.kv, self.mass, self.ki * dt, self.i_limit, self.tan_tilt, self.min_fz,
            self.weight, self.f_max, self.obs_tau, self.obs_limit, *self.J, *self.kR, *self.kW,
        ]  # fmt: skip

    def __call__(self, drones, pos, vel, R, omega, thrust, ref, dt: float) -> np.ndarray:
        """Rotor thrusts (m, 4) for ``drones``: the compiled law as a
        :class:`~cpp_mujoco.physics.parts.Controller` (the flight runs the same kernel fused
        into its tick when this is its controller)."""
        m = len(drones)
        out = np.empty((m, 4))
        rows = [np.ascontiguousarray(x, dtype=float).reshape(m, -1)
                for x in (pos, vel, R, omega, thrust, ref)]  # fmt: skip
        if self._constants is None or self._constants[0] != dt:  # built once per interval
            self._constants = (dt, control_constants(dt, controller=self))
        kernels.thrusts(
            np.asarray(drones, dtype=np.int64), *rows, self._constants[1],
            self.A_inv, self.integral, self.disturbance, self.last_vel, self.last_force,
            self.has_last, out,
        )  # fmt: skip
        return out
