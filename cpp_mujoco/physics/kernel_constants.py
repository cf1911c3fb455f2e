"""The one array of constants the compiled kernels read, packed from the flight's parts.

Each part contributes its own numbers (wind, controller, rotor energy, battery pack); the
kernels of :mod:`~cpp_mujoco.physics.tick_kernels` and :mod:`~cpp_mujoco.physics.power.kernels`
read them by position. A part used alone (the controller or the wind outside a flight) packs
only its own and reads zeros for the others.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cpp_mujoco.physics.power.battery import OCV

if TYPE_CHECKING:
    from cpp_mujoco.physics.air.wind import Wind
    from cpp_mujoco.physics.control.controller import GeometricController
    from cpp_mujoco.physics.power.battery import PackSpec
    from cpp_mujoco.physics.power.rotor import IntervalEnergy

GRAVITY = 9.81  # m/s²
# tabled turbulence time scales: airspeeds up to e^(key·0.5 %) ≈ 1e35 m/s; a drone's airspeed
# past that (or NaN) has diverged already, and its turbulence turns NaN (it fails next tick)
MAX_KEYS = 1 << 14


def control_constants(
    dt: float,
    wind: Wind | None = None,
    controller: GeometricController | None = None,
    energy: IntervalEnergy | None = None,
    spec: PackSpec | None = None,
    half_rho_cda: float = 0.0,
) -> np.ndarray:
    """The constants the kernels read, in their order: wind (and gravity), the control
    interval, controller, energy, battery, drag, turbulence, the OCV curve, the turbulence
    table's size limit (the parts left out read as zeros: one part alone)."""
    w, e = wind, energy
    turb = w.turbulence if w is not None else None
    return np.array([
        *((w.std, w.decay, w.kick) if w else [0.0] * 3), GRAVITY, w.dt if w else dt,
        dt, *(controller.constants(dt) if controller is not None else [0.0] * 20),
        *([e.power.coef, e.power.avionics * len(e.decay), e.dt, e.mean_decay] if e else [0.0] * 4),
        *((spec.cells, spec.resistance, spec.cutoff_v) if spec else [0.0] * 3), half_rho_cda,
        turb is not None, *((turb.min_airspeed, turb.per_log, *turb.gain) if turb else [0.0] * 5),
        *OCV, MAX_KEYS,
    ], dtype=float)  # fmt: skip
