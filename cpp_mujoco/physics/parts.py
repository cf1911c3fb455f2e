"""The swappable parts of a :class:`~cpp_mujoco.physics.flight.Flight`: what the flight calls.

A flight is a vehicle (the compiled MJCF) flown by a controller through a wind, after RotorPy's
vehicle / controller / wind split: ``Flight(model, grid_map, config, controller=…, wind=…)``.
``None`` builds the defaults (:class:`~cpp_mujoco.physics.control.controller.GeometricController` with
``config.controller`` gains, :class:`~cpp_mujoco.physics.air.wind.Wind` from ``config``'s weather).

Both are called at the control rate from a plain-float loop: take and return plain floats and
tuples (rotation matrices are row-major 9-sequences, body→world), not numpy arrays — a numpy call
per tick would cost more than the physics step. Note: ``MuJoCo-v0`` always flies the default parts
(its budget unit is calibrated with them); custom parts are for :class:`Flight` users.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np

Vec3 = Sequence[float]


@runtime_checkable
class Controller(Protocol):
    """Turns the state and a reference into four rotor thrusts (N), once per control update."""

    lead: float  # s, how far ahead the flight's minimum-jerk reference gives the acceleration

    def reset(self) -> None:
        """Forget all internal state (integrators, observers): a new episode starts."""

    def hover_thrust(self) -> float:
        """Per-rotor thrust (N) the episode starts with, rotors spun up, hovering."""

    def observe(self, vel: Vec3, R: Sequence[float], thrusts: Sequence[float], dt: float) -> None:
        """Called before every update with the measured rotor thrusts (``data.act``)."""

    def __call__(
        self, pos: Vec3, vel: Vec3, R: Sequence[float], omega: Vec3,
        ref_p: Vec3, ref_v: Vec3, ref_a: Vec3, dt: float,
    ) -> Sequence[float]:  # fmt: skip
        """Rotor thrusts for world position/velocity, attitude, body rates and the reference."""


@runtime_checkable
class WindModel(Protocol):
    """The air's velocity (m/s, world frame) at the vehicle, once per control update, in order.

    The flight turns it into drag on the body (:class:`~cpp_mujoco.physics.air.wind.QuadraticDrag`).
    """

    def reset(self, rng: np.random.Generator) -> None:
        """A new episode; ``rng`` is the env's generator (seeded by ``reset(seed=…)``)."""

    def velocity(self, time: float, position: Vec3) -> tuple[float, float, float]:
        """Wind at simulated ``time`` (s) and the body's world ``position``; stateful models
        advance by one control interval per call."""
