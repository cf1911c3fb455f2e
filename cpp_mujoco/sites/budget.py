"""A movement budget from a battery, through the physics' own calibration.

The budget unit is the energy one nominal move draws from the pack at this cell size, altitude
and speed (:func:`cpp_mujoco.physics.calibration.unit_energy`: a calm-air move flown in MuJoCo,
pack losses included, plus the unit margin). The pack's usable energy less the reserve (never
planned with: what is left at landing) and less the take-off climb (the episode starts in the
air) is divided by it, rounded down. The landing is one of the budget's actions.

Speed: a move is a minimum-jerk flight of one cell, whose peak speed is 1.875 × cell / duration;
the cruise speed is that peak, the speed the autopilot is given, so a move lasts
1.875 × cell / cruise speed (the physics' default: 4 m at 2.5 m/s, 3 s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cache

import mujoco

from cpp_mujoco.physics.calibration import calibration, unit_energy
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.quadrotor import QuadrotorParams, quadrotor_xml

MIN_JERK_PEAK = 1.875  # a minimum-jerk move's peak speed over its mean speed
WH = 3600.0  # J in a watt-hour


@dataclass(frozen=True)
class FlightSettings:
    """How the drone flies the site: the physics is configured from these."""

    # m above the take-off point: the camera's altitude (the physics' default; a 90° camera
    # sees 3x3 cells of 4 m from there)
    altitude: float = 6.0
    cruise_speed: float = 2.5  # m/s, a move's peak speed (the physics' default: 4 m in 3 s)
    wind_speed: float = 0.0  # m/s, steady wind the mission is planned and flown in
    wind_direction: float = 0.0  # deg, where the wind blows from, clockwise from true north

    def __post_init__(self) -> None:
        for name in ("altitude", "cruise_speed"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value}")
        if not (math.isfinite(self.wind_speed) and self.wind_speed >= 0):
            raise ValueError(f"wind_speed must be a finite number >= 0, got {self.wind_speed}")


@dataclass(frozen=True)
class Battery:
    """The pack the mission is flown on."""

    # Wh the pack delivers from full charge to its cut-off: about 80 % of a 3S 2200 mAh pack
    usable_wh: float = 20.0
    reserve: float = 0.2  # share of the usable energy still in the pack at landing
    climb_speed: float = 1.5  # m/s, the take-off climb (PX4's MPC_TKO_SPEED default)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.usable_wh) and self.usable_wh > 0):
            raise ValueError(f"usable energy must be a finite number of Wh > 0: {self.usable_wh}")
        if not 0 <= self.reserve < 1:
            raise ValueError(f"reserve must be a share in [0, 1), got {self.reserve}")
        if not (math.isfinite(self.climb_speed) and self.climb_speed > 0):
            raise ValueError(f"climb speed must be a finite number > 0, got {self.climb_speed}")


def physics_config(flight: FlightSettings, cell_size: float, heading: float) -> PhysicsConfig:
    """The physics for this site: its cell, the camera altitude, a move at the cruise speed,
    and the wind turned into the map's frame (whose "north" points ``heading`` from true north).
    A move may take as long beyond its duration as the default allows (8 s for 3 s)."""
    base = PhysicsConfig()
    duration = MIN_JERK_PEAK * cell_size / flight.cruise_speed
    return replace(
        base,
        cell_size=float(cell_size),
        altitude=float(flight.altitude),
        move_duration=duration,
        move_time_limit=max(
            base.move_time_limit, base.move_time_limit / base.move_duration * duration
        ),  # fmt: skip
        wind_speed=float(flight.wind_speed),
        wind_direction=float((flight.wind_direction - heading) % 360.0),
    )


@dataclass(frozen=True)
class Budget:
    """A battery's energy in budget units, every term stated."""

    units: int  # the episode's budget: moves, hovers and the landing, one unit each
    unit_energy_j: float  # J, a nominal move at this cell, altitude and speed (calibrated)
    usable_j: float  # J, the pack's usable energy
    reserve_j: float  # J, kept in the pack at landing
    takeoff_j: float  # J, the climb to the camera altitude (estimated)
    planned_j: float  # J, the budget: units × unit energy

    @property
    def margin_j(self) -> float:
        """J left over by rounding the budget down to whole units."""
        return self.usable_j - self.reserve_j - self.takeoff_j - self.planned_j

    def as_dict(self) -> dict[str, float | int]:
        return {
            "units": self.units,
            "unit_energy_j": self.unit_energy_j,
            "usable_wh": self.usable_j / WH,
            "reserve_wh": self.reserve_j / WH,
            "takeoff_wh": self.takeoff_j / WH,
            "budget_wh": self.planned_j / WH,
            "rounding_wh": self.margin_j / WH,
        }

    def lines(self) -> list[str]:
        """The arithmetic, for a person."""
        return [
            f"usable {self.usable_j / WH:.2f} Wh - reserve {self.reserve_j / WH:.2f} Wh - take-off "
            f"{self.takeoff_j / WH:.3f} Wh = {(self.planned_j + self.margin_j) / WH:.2f} Wh",
            f"/ {self.unit_energy_j:.1f} J a move = {self.units} units "
            f"({self.planned_j / WH:.2f} Wh planned, {self.margin_j:.0f} J rounded off)",
        ]


@cache
def _weight_n() -> float:
    """N, the airframe's weight (the MJCF model the physics flies)."""
    model = mujoco.MjModel.from_xml_path(str(quadrotor_xml()))
    return QuadrotorParams.from_model(model, prefix="").weight


def takeoff_energy(config: PhysicsConfig, climb_speed: float) -> float:
    """J to climb to ``config.altitude``: the calibrated hover power over the climb's duration
    plus the potential energy gained (an estimate: the physics flies no take-off)."""
    hover_w = float(calibration(config)["hover_power_w"])
    return hover_w * config.altitude / climb_speed + _weight_n() * config.altitude


def budget_of(battery: Battery, config: PhysicsConfig) -> Budget:
    """The budget ``battery`` gives a mission flown with ``config``; refused below one unit."""
    unit = unit_energy(config)
    usable = battery.usable_wh * WH
    reserve = usable * battery.reserve
    takeoff = takeoff_energy(config, battery.climb_speed)
    units = math.floor((usable - reserve - takeoff) / unit)
    if units < 2:
        raise ValueError(
            f"a pack of {battery.usable_wh:g} Wh usable with a {battery.reserve:.0%} reserve "
            f"holds {max(units, 0)} move(s) of {unit:.0f} J after the take-off; a mission needs "
            "a move and a landing at least"
        )
    return Budget(units, unit, usable, reserve, takeoff, units * unit)
