"""The swappable parts of a :class:`~cpp_mujoco.physics.flight.Flight`: what the flight calls.

A flight is a vehicle (the compiled MJCF) flown by a controller through a wind, after RotorPy's
vehicle / controller / wind split. Both parts work on arrays over the drones of a batch, so one
call per control tick serves them all. The envs take them as options
(``gym.make("cpp_mujoco/MuJoCo-v0", wind_model=…, controller_model=…)``, the same on
``make_vec``); None flies the built-in ones,
:class:`~cpp_mujoco.physics.control.controller.GeometricController` with ``config.controller``
gains and :class:`~cpp_mujoco.physics.air.wind.Wind` from ``config``'s weather, which run fused
into the compiled tick and are themselves parts (``Wind.velocity``, ``GeometricController``'s
compiled law through :func:`~cpp_mujoco.physics.tick_kernels.thrusts`).

The budget unit stays the calibration of the built-in parts in calm air: a part that flies a
move more cheaply gets more moves out of a budget, which is the point of comparing parts.
``docs/physics.md`` has a worked example of a user's wind.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Controller(Protocol):
    """Turns the drones' states and references into rotor thrusts, once per control tick."""

    lead: float  # s, how far ahead the reference gives its acceleration

    def reset(self, i: int) -> None:
        """Drone ``i`` starts an episode: forget its internal state (integrators, observers)."""

    def hover_thrust(self) -> float:
        """Per-rotor thrust (N) an episode starts with, rotors spun up, hovering."""

    def __call__(
        self, drones: np.ndarray, pos: np.ndarray, vel: np.ndarray, R: np.ndarray,
        omega: np.ndarray, thrust: np.ndarray, ref: np.ndarray, dt: float,
    ) -> np.ndarray:  # fmt: skip
        """Rotor thrusts (m, 4) in N for ``drones`` (m,): world positions and velocities
        (m, 3), body→world rotations (m, 3, 3), body rates (m, 3), the rotors' current thrusts
        (m, 4, ``data.act``) and the references (m, 3, 3: rows position, velocity,
        acceleration). The flight clips them to the rotors' range."""


@runtime_checkable
class WindModel(Protocol):
    """The air's velocity (m/s, world frame) at the drones, once per control tick, in order.

    The flight turns it into drag on the body (½ρ·C_dA·|v_rel|·v_rel) and into the airspeed
    through the rotors (forward-flight power)."""

    def reset(self, i: int, rng: np.random.Generator) -> None:
        """Drone ``i`` starts an episode; ``rng`` is its own generator (seeded by
        ``reset(seed=…)``)."""

    def velocity(self, drones: np.ndarray, time: np.ndarray, position: np.ndarray) -> np.ndarray:
        """The wind (m, 3) at the drones' simulated ``time`` (m,) and world ``position``
        (m, 3); stateful models advance by one control interval per call."""
