"""Electrical power from rotor thrust and airspeed, and its integral over a control interval.

Two models (``PhysicsConfig.power_model``):

* ``"momentum"`` (the default for now) — hover momentum theory: per rotor
  P = T^1.5 / √(2ρA) / η (actuator disk, η the overall electrical → ideal-induced
  efficiency), whatever the airspeed.
* ``"forward-flight"`` — per rotor, with the air-relative velocity through the disk
  (body velocity − wind, in the body frame: V⊥ along the rotor axis, V∥ in the disk plane):
  Glauert's induced velocity v_i = T / (2ρA·√(V∥² + (V⊥ + v_i)²)) (Newton steps), induced and
  axial-flow power T·(κ·v_i + V⊥), blade profile power P0·(1 + K·μ²) with μ = V∥/(ΩR), divided
  by the motor × ESC efficiency; plus avionics. T·V⊥ is the work the rotors do against the
  airframe's drag (and gravity when climbing): the flight tilts the rotors to balance the drag it
  applies, so the parasite power is counted through the thrust, once. In still air it equals the
  momentum model exactly: P0 and κ are split out of the same hover figure of merit.

See ``docs/power.md`` for the derivation, the parameters' sources and the power curve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from math import sqrt

import numpy as np

from cpp_mujoco.physics.power import kernels
from cpp_mujoco.physics.quadrotor import QuadrotorParams


class PowerModel:
    """Battery power in hover (momentum theory) as a function of the four rotor thrusts."""

    def __init__(self, params: QuadrotorParams, air_density: float = 1.225):
        disk = math.pi * params.rotor_radius**2
        self.coef = 1.0 / (math.sqrt(2 * air_density * disk) * params.power_efficiency)
        self.avionics = params.avionics_power

    def power(self, thrusts) -> float:
        """W drawn while the rotors produce ``thrusts`` (N each)."""
        c = self.coef
        return self.avionics + sum(c * t**1.5 for t in thrusts if t > 0.0)


@dataclass(frozen=True)
class RotorAero:
    """Rotor aerodynamics the forward-flight model adds (sources: ``assets/README.md``)."""

    figure_of_merit: float = 0.65  # hover FM of a small fixed-pitch propeller (0.5-0.7)
    induced_factor: float = 1.15  # κ, non-uniform inflow and tip losses (Leishman: 1.15)
    # C_T = T / (ρA(ΩR)²), rotorcraft convention: 10×4.5 prop C_T,n ≈ 0.11 (T = C_T,n·ρn²D⁴)
    # is 0.11·4/π³ = 0.0142; it sets the tip speed ΩR = √(T / (ρA·C_T)) ≈ 65 m/s in hover
    thrust_coefficient: float = 0.0142
    profile_mu_factor: float = 4.65  # K in P0·(1 + K·μ²) (Bramwell; 3 for the simplest form)
    vrs_limit: float = 0.5  # V⊥ is clamped at −vrs_limit·v_h: vortex-ring state guard
    newton_steps: int = 4  # measured: power within 1e-9 of the converged root


class ForwardFlightPower:
    """Per-rotor power in moving air, normalised so that it equals :class:`PowerModel` in still
    air at every thrust (both scale as T^1.5 there). The rule is the compiled
    :func:`~cpp_mujoco.physics.power.kernels.ratio` (P_forward / P_hover for one rotor); this
    holds its constants (:meth:`constants`)."""

    def __init__(
        self, params: QuadrotorParams, air_density: float = 1.225, aero: RotorAero = RotorAero()
    ):
        disk = math.pi * params.rotor_radius**2
        self.hover = PowerModel(params, air_density)
        self.aero = aero
        self.inv_2rho_a = 1.0 / (2 * air_density * disk)
        self.ct_rho_a = aero.thrust_coefficient * air_density * disk  # μ² = V∥²·ρAC_T / T
        fm, kappa = aero.figure_of_merit, aero.induced_factor
        if not (0 < fm and 1 / fm > kappa >= 1):
            raise ValueError("RotorAero: need 1 <= induced_factor < 1 / figure_of_merit")
        # mechanical hover power T·v_h / FM = T·v_h·(κ + p0): p0 is the profile share
        self.kappa = kappa * fm  # all terms below are in units of T·v_h/FM
        self.p0 = (1.0 / fm - kappa) * fm
        self.fm = fm
        self.motor_efficiency = params.power_efficiency / fm  # motor × ESC
        self.k_mu = aero.profile_mu_factor
        self.vrs = aero.vrs_limit

    def constants(self) -> np.ndarray:
        """The kernels' ``f``: inv_2rho_a, vrs, ct_rho_a, kappa, fm, k_mu, p0, Newton steps, 1."""
        return np.array([
            self.inv_2rho_a, self.vrs, self.ct_rho_a, self.kappa, self.fm, self.k_mu, self.p0,
            self.aero.newton_steps, 1.0,
        ])  # fmt: skip

    def induced_velocity(self, thrust: float, v_par: float, v_perp: float) -> float:
        """Glauert's v_i (m/s) for one rotor, V⊥ clamped at −vrs_limit·v_h first."""
        vh2 = thrust * self.inv_2rho_a
        return kernels.induced(vh2, v_par, max(v_perp, -self.vrs * sqrt(vh2)), self.constants())

    def power(self, thrusts, air_body) -> float:
        """W drawn with rotor ``thrusts`` (N) and the body's velocity relative to the air in
        the body frame, ``air_body`` (m/s; z along the rotor axes)."""
        v_par, v_perp, f = math.hypot(air_body[0], air_body[1]), air_body[2], self.constants()
        c = self.hover.coef
        total = sum(c * t**1.5 * kernels.ratio(t, v_par, v_perp, f) for t in thrusts if t > 0.0)
        return self.hover.avionics + total


class IntervalEnergy:
    """The energy of ``substeps`` MuJoCo steps holding ``ctrl`` constant, summed step by step
    (the rule: :func:`~cpp_mujoco.physics.power.kernels.power`; here its constants).

    With ``dyntype="filter"`` MuJoCo integrates the rotor state by explicit Euler,
    ``act ← act + dt·(ctrl − act)/τ``, and each step's force is the ``act`` at its start — so the
    thrust of every physics step is known in closed form from ``act`` and ``ctrl`` at the start of
    the interval: ``act_k = ctrl + (act_0 − ctrl)·aᵏ`` with ``a = 1 − dt/τ``. Summing
    P(act_k)·dt over k is the physics-step integral, at controller-rate cost.

    With ``forward`` each rotor's per-step hover integral is scaled by its forward-flight
    ratio, evaluated once per tick at the rotor's mean thrust over the interval and the tick's
    airspeed.
    """

    def __init__(
        self,
        power: PowerModel,
        timestep: float,
        motor_tau: float,
        substeps: int,
        forward: ForwardFlightPower | None = None,
    ):
        a = 1.0 - timestep / motor_tau
        self.decay = np.array([a**k for k in range(substeps)])
        self.mean_decay = sum(a**k for k in range(substeps)) / substeps
        self.power = power
        self.forward = forward
        self.dt = timestep


def level_flight_power(
    model: ForwardFlightPower, params: QuadrotorParams, air_density: float, airspeed: float
) -> dict[str, float]:
    """Trimmed level flight at ``airspeed`` (m/s) in still air: the four rotors' thrust balances
    weight and the airframe's drag ½ρC_dA·V², the body pitched nose-down by atan(D/W).

    Returns the battery power (W) and its parts (W, electrical): induced, drag (parasite),
    profile, avionics; and the trim (thrust per rotor N, pitch deg, induced velocity m/s).
    """
    weight = params.weight
    drag = 0.5 * air_density * params.drag_area * airspeed * airspeed
    pitch = math.atan2(drag, weight)
    thrust = math.hypot(weight, drag) / 4
    v_par, v_perp = airspeed * math.cos(pitch), airspeed * math.sin(pitch)
    vp = max(v_perp, -model.vrs * math.sqrt(thrust * model.inv_2rho_a))
    v_i = model.induced_velocity(thrust, v_par, v_perp)
    eta = model.motor_efficiency
    hover_mech = model.hover.coef * thrust**1.5 * params.power_efficiency  # T·v_h per rotor
    mu2 = v_par * v_par * model.ct_rho_a / thrust
    parts = {
        "induced_w": 4 * thrust * model.aero.induced_factor * v_i / eta,
        "drag_w": 4 * thrust * vp / eta,
        "profile_w": 4 * hover_mech * (model.p0 / model.fm) * (1 + model.k_mu * mu2) / eta,
        "avionics_w": model.hover.avionics,
    }
    return {
        "airspeed_m_s": airspeed,
        "power_w": model.power([thrust] * 4, (v_par, 0.0, v_perp)),
        **parts,
        "thrust_per_rotor_n": thrust,
        "pitch_deg": math.degrees(pitch),
        "induced_velocity_m_s": v_i,
        "advance_ratio": math.sqrt(mu2),
    }
