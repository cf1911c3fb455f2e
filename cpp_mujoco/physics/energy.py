"""Electrical power from rotor thrust (momentum theory) and its exact integral over a control
interval.

Ideal induced power of a rotor in hover is P = T^1.5 / √(2ρA) (actuator-disk theory); dividing by
an overall efficiency η (figure of merit × motor × ESC) gives the electrical draw. Forward-flight
induced-power relief is ignored, so the model is conservative at speed.
"""

from __future__ import annotations

import math
from math import sqrt

from cpp_mujoco.physics.quadrotor import QuadrotorParams


class PowerModel:
    """Battery power as a function of the four rotor thrusts."""

    def __init__(self, params: QuadrotorParams, air_density: float = 1.225):
        disk = math.pi * params.rotor_radius**2
        self.coef = 1.0 / (math.sqrt(2 * air_density * disk) * params.power_efficiency)
        self.avionics = params.avionics_power

    def power(self, thrusts) -> float:
        """W drawn while the rotors produce ``thrusts`` (N each)."""
        c = self.coef
        return self.avionics + sum(c * t**1.5 for t in thrusts if t > 0.0)


class IntervalEnergy:
    """Energy of ``n`` MuJoCo steps holding ``ctrl`` constant, summed step by step.

    With ``dyntype="filter"`` MuJoCo integrates the rotor state by explicit Euler,
    ``act ← act + dt·(ctrl − act)/τ``, and each step's force is the ``act`` at its start — so the
    thrust of every physics step is known in closed form from ``act`` and ``ctrl`` at the start of
    the interval: ``act_k = ctrl + (act_0 − ctrl)·aᵏ`` with ``a = 1 − dt/τ``. Summing
    P(act_k)·dt over k is the physics-step integral, at controller-rate cost.
    """

    def __init__(self, power: PowerModel, timestep: float, motor_tau: float, substeps: int):
        a = 1.0 - timestep / motor_tau
        self.decay = tuple(a**k for k in range(substeps))
        self.power = power
        self.dt = timestep

    def __call__(self, act0, ctrl) -> float:
        # every act_k lies between act_0 and ctrl (both >= 0), so t·√t is safe
        total = 0.0
        for a0, u in zip(act0, ctrl):  # noqa: B905 - four rotors each
            d = a0 - u
            for w in self.decay:
                t = u + d * w
                total += t * sqrt(t)
        return (self.power.coef * total + self.power.avionics * len(self.decay)) * self.dt
