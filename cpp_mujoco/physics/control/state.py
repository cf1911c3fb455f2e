"""The per-drone state of the flight's references and controller: the arrays the compiled tick
(:mod:`~cpp_mujoco.physics.control.kernels`) reads and writes.

Arrays are (n, 3) vectors and (n,) flags, one row per drone of a batch.
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.physics.control.controller import GeometricController


class References:
    """Per drone: a rest-to-rest minimum-jerk path
(:class:`~cpp_mujoco.physics.control.controller.MinJerk`), or the
    landing descent (min-jerk to a flare above the touchdown point, then a constant sink); the
    compiled ``sense`` evaluates it each tick."""

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


class BatchedController:
    """:class:`~cpp_mujoco.physics.control.controller.GeometricController`'s state for n drones (its
    gains and mixer are the scalar controller's, built from the same parameters)."""

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
