"""Everything configurable about the physics backend, with documented defaults.

Geometry (why these numbers): a 4 m cell seen from 6 m gives a 90° square camera for the paper's
3×3 field of view — a common wide-angle mapping camera; a 16×16 map is then 64 m × 64 m, one
mission of a small quadrotor. Timing: a move is a minimum-jerk flight of one cell in
``move_duration`` (peak speed 1.875·cell/duration = 2.5 m/s, peak tilt ≈ 12°), gentle enough for
a camera survey.
"""

from __future__ import annotations

import hashlib
import json
import math
import numbers
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from cpp_mujoco.physics.air.turbulence import check_level

# fields that do not change how a calm-air move flies (so they do not change the energy unit)
_NOT_CALIBRATED = {
    "wind_speed", "wind_direction", "gust_std", "gust_tau", "turbulence", "unit_margin",
    "battery_cutoff_v", "return_guard", "gust_seed", "building_height_m", "low_obstacle_height_m",
}  # fmt: skip

_INF = math.inf
# m a low obstacle stays below the cruise altitude at least: the airframe reaches 0.36 m below the
# camera, the controller holds the altitude within centimetres in calm air; the rest is room for
# gusts pushing the UAV down
LOW_OBSTACLE_CLEARANCE = 2.0
# the first is the default; "forward-flight" changes what hovering and moving in wind cost
POWER_MODELS = ("forward-flight", "momentum")  # the first is the default
# field: (low, high, low included, high included); every field must also be a finite number.
# Upper bounds only where the physics breaks beyond them: a timestep past 20 ms is half the
# 40 ms rotor lag (Euler on the filter); tilts are angles.
_RANGES: dict[str, tuple[float, float, bool, bool]] = {
    "cell_size": (0, _INF, False, False),
    "altitude": (0, _INF, False, False),
    "building_height_m": (0, _INF, False, False),
    "low_obstacle_height_m": (0, _INF, False, False),
    "timestep": (0, 0.02, False, True),
    "control_rate": (0, _INF, False, False),
    "camera_rate": (0, _INF, False, False),
    "move_duration": (0, _INF, False, False),
    "move_time_limit": (0, _INF, False, False),
    "arrive_pos_tol": (0, _INF, False, False),
    "arrive_vel_tol": (0, _INF, False, False),
    "land_duration": (0, _INF, False, False),
    "land_speed": (0, _INF, False, False),
    "land_time_limit": (0, _INF, False, False),
    "fall_time_limit": (0, _INF, False, False),
    "max_frame_tilt_deg": (0, 90, False, True),
    "max_tilt_deg": (0, 180, False, True),
    "max_tracking_error": (0, _INF, False, False),
    "unit_margin": (0, 0.5, True, False),
    "air_density": (0, _INF, False, False),
    "wind_speed": (0, _INF, True, False),
    "wind_direction": (-_INF, _INF, False, False),
    "gust_std": (0, _INF, True, False),
    "gust_tau": (0, _INF, False, False),
    "battery_cells": (1, _INF, True, False),
    "battery_cell_resistance": (0, _INF, True, False),
    "battery_cutoff_v": (0, _INF, True, False),
    "battery_reserve": (0, 1, True, False),
}


def _describe(lo: float, hi: float, lo_closed: bool, hi_closed: bool) -> str:
    """``"a finite number > 0"``, ``"in [0, 0.5)"``… for error messages."""
    if hi == _INF and lo == -_INF:
        return "a finite number"
    if hi == _INF:
        return f"a finite number {'>=' if lo_closed else '>'} {lo:g}"
    return f"in {'[' if lo_closed else '('}{lo:g}, {hi:g}{']' if hi_closed else ')'}"


def _check_numbers(obj: object, ranges: dict, prefix: str = "") -> None:
    """Reject a non-number or an out-of-range value of ``obj``'s fields; store them as floats
    (so ints and numpy scalars hash and compare like the floats they stand for)."""
    for name, (lo, hi, lo_closed, hi_closed) in ranges.items():
        value = getattr(obj, name)
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
            raise ValueError(f"{prefix}{name} must be a number, got {value!r}")
        number = float(value)
        if not (
            math.isfinite(number)
            and (number >= lo if lo_closed else number > lo)
            and (number <= hi if hi_closed else number < hi)
        ):
            raise ValueError(
                f"{prefix}{name} must be {_describe(lo, hi, lo_closed, hi_closed)}, got {value!r}"
            )
        object.__setattr__(obj, name, number)


_POSITIVE, _NON_NEGATIVE = (0, _INF, False, False), (0, _INF, True, False)
_GAIN_RANGES: dict[str, tuple[float, float, bool, bool]] = {
    "position_bw": _POSITIVE,
    "position_damping": _POSITIVE,
    "position_integral": _NON_NEGATIVE,
    "integral_limit": _NON_NEGATIVE,
    "observer_tau": _NON_NEGATIVE,
    "observer_limit": _NON_NEGATIVE,
    "attitude_bw": _POSITIVE,
    "attitude_damping": _POSITIVE,
    "yaw_bw": _POSITIVE,
    "tilt_limit_deg": (0, 90, False, False),
    "feedforward_lead": _NON_NEGATIVE,
}


@dataclass(frozen=True)
class ControllerGains:
    """The geometric controller's loop bandwidths; its gains follow from these and the
    airframe's mass and inertia (``GeometricController``).

    Defaults: position at 2 rad/s and attitude at 12 rad/s keep each loop ≥ 5× slower than the
    next (attitude vs. the 25 rad/s rotor lag), the usual cascade separation. Set them as
    ``PhysicsConfig(controller=ControllerGains(position_bw=3))`` or, through ``gymnasium.make``,
    ``controller={"position_bw": 3}``; they are part of the calibration key, so the budget unit
    is re-measured with the controller that flies.
    """

    position_bw: float = 2.0  # rad/s
    position_damping: float = 0.9
    position_integral: float = 0.0  # 1/s, integral gain relative to the proportional gain
    integral_limit: float = 3.0  # N, anti-windup bound of the integral force
    observer_tau: float = 0.15  # s, low-pass time constant of the external-force observer
    observer_limit: float = 21.0  # N, bound of the estimated external force (= W·tan 55°)
    attitude_bw: float = 12.0  # rad/s (roll, pitch)
    attitude_damping: float = 0.8
    yaw_bw: float = 4.0  # rad/s
    # the commanded force is tilted at most this much. 55° holds the altitude with 80 % of the
    # 32 N maximum thrust (W / cos 55° = 25.7 N), leaving 20 % for attitude control, and
    # balances W·tan 55° = 21 N of drag: a 20.7 m/s relative airspeed, i.e. a 9 m/s wind plus a
    # 3.9σ gust of moderate turbulence (σ_u = 3.0 m/s at 6 m). At 45° (and a 12 N observer) the
    # 18 m/s gust peaks of that weather blew the UAV 5 m off its track.
    tilt_limit_deg: float = 55.0
    feedforward_lead: float = 0.1  # s, reference acceleration taken this far ahead (References)

    def __post_init__(self) -> None:
        _check_numbers(self, _GAIN_RANGES, prefix="controller.")

    @classmethod
    def from_value(cls, value: object) -> ControllerGains:
        """``value`` as gains: a ``ControllerGains`` or a mapping of some of its fields."""
        if isinstance(value, cls):
            return value
        if isinstance(value, Mapping):
            names = {f.name for f in fields(cls)}
            unknown = sorted(str(k) for k in value if k not in names)
            if unknown:
                raise ValueError(f"controller: unknown gain(s) {unknown}; known: {sorted(names)}")
            return cls(**value)
        raise ValueError(
            f"controller must be ControllerGains or a dict of its fields, got {value!r}"
        )


@dataclass(frozen=True)
class PhysicsConfig:
    """Physical configuration of the arena, the flight and the weather."""

    # --- grid ↔ world
    cell_size: float = 4.0  # m, side of one grid cell on the ground
    altitude: float = 6.0  # m, cruise height of the camera above the ground
    # --- obstacles, on maps that have them (cpp_mujoco/physics/obstacles.py): a building rises
    # above the cruise altitude (blocks flight and view), a low obstacle stays below it with
    # room to fly over (blocks view only)
    building_height_m: float = 16.0  # m, the default cruise altitude + 10 m
    low_obstacle_height_m: float = 2.0  # m, the default cruise altitude − 4 m
    # --- simulation and control rates
    timestep: float = 0.004  # s, MuJoCo step (Euler); the 40 ms rotor lag is 10 steps
    control_rate: float = 50.0  # Hz, geometric controller (a whole number of physics steps)
    camera_rate: float = 10.0  # Hz, frames used for coverage
    # --- macro-steps (one grid action)
    move_duration: float = 3.0  # s, nominal min-jerk flight of one cell; also a rejected hover
    move_time_limit: float = 8.0  # s, a move that has not arrived by then ends anyway
    arrive_pos_tol: float = 0.2  # m, arrival: distance to the cell centre …
    arrive_vel_tol: float = 0.2  # m/s, … and speed below these
    # a landing must cost less than one budget unit, as every grid action costs one: an agent
    # that lands with its last unit must not run dry in the descent (2.2 s + 0.8 m/s ≈ 0.87 units)
    land_duration: float = 2.2  # s, min-jerk descent to just above the ground
    land_speed: float = 0.8  # m/s, final sink rate until the landing gear touches
    land_time_limit: float = 12.0  # s, no touchdown by then is a failure
    fall_time_limit: float = 5.0  # s, how long a motor-cut fall is simulated before the crash
    # --- mapping: a cell is seen when its centre lies in the camera footprint *and* within the
    # nominal (level, cruise-altitude) footprint around the camera's nadir point: beyond it the
    # ground resolution is coarser than the mission algorithm is designed for. Without this, a
    # 12° acceleration tilt of the 90° camera stretches the far edge from 1.5 to 2.3 cells and
    # sees a row the grid never does; steady wind tilts are tolerated. Frames more than
    # ``max_frame_tilt_deg`` off nadir are not used at all.
    max_frame_tilt_deg: float = 30.0
    # --- failure detection
    max_tilt_deg: float = 80.0  # body tilt beyond this is a flip
    max_tracking_error: float = 8.0  # m, beyond this the flight has diverged
    # --- the budget unit: a calibrated calm-air move, plus this margin. Real moves scatter by a
    # few tenths of a percent around the calibration; without a margin ⌊remaining / unit⌋ can
    # fall one unit behind the grid's count after the first move, and an agent that lands on its
    # last grid unit would see 0 and end as a crash with most of a unit left.
    unit_margin: float = 0.02
    # --- weather (default calm)
    air_density: float = 1.225  # kg/m³, ISA sea level
    wind_speed: float = 0.0  # m/s, steady wind
    wind_direction: float = 0.0  # deg, where the wind blows FROM, clockwise from north (0 = north)
    gust_std: float = 0.0  # m/s, standard deviation of each horizontal gust component
    gust_tau: float = 2.0  # s, correlation time of the Ornstein-Uhlenbeck gusts
    # Dryden turbulence (MIL-F-8785C, low altitude) on top: "none", "light", "moderate",
    # "severe" (W20 = 15 / 30 / 45 kt); see cpp_mujoco/physics/air/turbulence.py
    turbulence: str = "none"
    # 0: an episode's gusts come from its own generator (seeded by the episode's seed); k > 0:
    # from a generator seeded by (k, one draw of it) — other gust histories for the very same
    # episodes, e.g. held-out gust seeds to choose agents on without touching the protocol's
    gust_seed: int = 0
    # --- rotor power (cpp_mujoco/physics/power/rotor.py, docs/power.md): "forward-flight" (Glauert
    # induced velocity with the airspeed through each disk, profile and drag power) or
    # "momentum" (hover momentum theory, airspeed-blind); both give the same hover in still air
    power_model: str = POWER_MODELS[0]
    # --- the LiPo pack (cpp_mujoco/physics/power/battery.py; sources in assets/README.md). An
    # episode's pack holds its budget of drawable energy between full charge and the reserve.
    battery_cells: int = 3  # in series
    battery_cell_resistance: float = 0.005  # Ω per cell, internal (DC) resistance
    battery_cutoff_v: float = 3.3  # V per cell under load; below it the failsafe lands
    battery_reserve: float = 0.1  # state of charge left when the budget is spent
    # --- the return guard (cpp_mujoco/physics/return_guard.py): when the energy left comes
    # down to the estimated way home, it takes over and flies to the nearest landing cell.
    # Off by default, so the paper's protocol is unchanged
    return_guard: bool = False
    # --- the waypoint controller's bandwidths (a dict of some fields is accepted too)
    controller: ControllerGains = field(default_factory=ControllerGains)

    def __post_init__(self) -> None:
        """Reject what would fly silently wrong numbers: NaN, inf, bools, strings, a zero
        ``gust_tau`` (division), a timestep the controller rate cannot be made of."""
        _check_numbers(self, _RANGES)
        check_level(self.turbulence, self.altitude)
        if (
            isinstance(self.gust_seed, (bool, np.bool_))
            or not isinstance(self.gust_seed, numbers.Integral)
            or not 0 <= self.gust_seed < 2**63
        ):
            raise ValueError(f"gust_seed must be an integer >= 0, got {self.gust_seed!r}")
        object.__setattr__(self, "gust_seed", int(self.gust_seed))
        if not isinstance(self.return_guard, (bool, np.bool_)):
            raise ValueError(f"return_guard must be True or False, got {self.return_guard!r}")
        object.__setattr__(self, "return_guard", bool(self.return_guard))
        if self.power_model not in POWER_MODELS:
            raise ValueError(
                f"power_model must be one of {', '.join(POWER_MODELS)}, got {self.power_model!r}"
            )
        object.__setattr__(self, "controller", ControllerGains.from_value(self.controller))
        ratio = 1.0 / (self.control_rate * self.timestep)
        if abs(ratio - round(ratio)) > 1e-6 * ratio or round(ratio) < 1:
            raise ValueError(
                f"control_rate ({self.control_rate} Hz) must be a whole number of physics steps "
                f"of timestep {self.timestep} s (1 / (control_rate * timestep) = {ratio:.6g})"
            )
        if self.move_time_limit < self.move_duration:
            raise ValueError(
                f"move_time_limit ({self.move_time_limit}) must be at least move_duration "
                f"({self.move_duration})"
            )
        if self.land_time_limit < self.land_duration:
            raise ValueError(
                f"land_time_limit ({self.land_time_limit}) must be at least land_duration "
                f"({self.land_duration})"
            )

    def check_obstacle_heights(self) -> None:
        """Reject obstacle heights that contradict their kind at this altitude; checked where a
        map with obstacles is built (a config flown only over open maps may set any altitude)."""
        if self.building_height_m <= self.altitude:
            raise ValueError(
                f"building_height_m ({self.building_height_m:g}) must be above the cruise "
                f"altitude ({self.altitude:g} m): a building blocks flight and view there"
            )
        if self.low_obstacle_height_m > self.altitude - LOW_OBSTACLE_CLEARANCE:
            raise ValueError(
                f"low_obstacle_height_m ({self.low_obstacle_height_m:g}) must be at most the "
                f"cruise altitude ({self.altitude:g} m) - {LOW_OBSTACLE_CLEARANCE:g} m: a low "
                "obstacle is flown over"
            )

    def gust_rng(self, rng: np.random.Generator) -> np.random.Generator:
        """The generator an episode's gusts are drawn from (:attr:`gust_seed`)."""
        if not self.gust_seed:
            return rng
        return np.random.default_rng([self.gust_seed, int(rng.integers(2**63))])

    @property
    def substeps(self) -> int:
        """Physics steps per controller update."""
        return max(1, round(1.0 / (self.control_rate * self.timestep)))

    @property
    def control_dt(self) -> float:
        return self.substeps * self.timestep

    @property
    def wind_vector(self) -> tuple[float, float, float]:
        """Steady wind velocity in the world frame (x east, y north), m/s."""
        rad = math.radians(self.wind_direction)
        return (-self.wind_speed * math.sin(rad), -self.wind_speed * math.cos(rad), 0.0)

    def calibration_key(self, extra: str = "") -> str:
        """Hash of every field that changes a calm-air move (plus ``extra``, e.g. model XML).

        Default gains (and battery fields at their defaults) are left out, so a default
        configuration keeps the key it had before they were configurable; a change of the
        defaults themselves reaches the key through ``extra`` (the calibration hashes this
        module's source).
        """
        relevant = {k: v for k, v in asdict(self).items() if k not in _NOT_CALIBRATED}
        if self.controller == ControllerGains():
            del relevant["controller"]
        if self.power_model == POWER_MODELS[0]:  # the default model: the key it had before
            del relevant["power_model"]
        for name in _BATTERY_DEFAULTS:
            if relevant.get(name) == _BATTERY_DEFAULTS[name]:
                del relevant[name]
        text = json.dumps(relevant, sort_keys=True) + extra
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    @classmethod
    def field_names(cls) -> set[str]:
        return {f.name for f in fields(cls)}


_BATTERY_DEFAULTS = {
    f.name: float(f.default) for f in fields(PhysicsConfig) if f.name.startswith("battery_")
}
