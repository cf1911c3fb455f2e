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
from dataclasses import asdict, dataclass, fields

# fields that do not change how a calm-air move flies (so they do not change the energy unit)
_NOT_CALIBRATED = {"wind_speed", "wind_direction", "gust_std", "gust_tau", "unit_margin"}


@dataclass(frozen=True)
class PhysicsConfig:
    """Physical configuration of the arena, the flight and the weather."""

    # --- grid ↔ world
    cell_size: float = 4.0  # m, side of one grid cell on the ground
    altitude: float = 6.0  # m, cruise height of the camera above the ground
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

    def __post_init__(self) -> None:
        for name in ("cell_size", "altitude", "timestep", "control_rate", "camera_rate"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if not 0.0 <= self.unit_margin < 0.5:
            raise ValueError(f"unit_margin must be in [0, 0.5), got {self.unit_margin}")
        if self.wind_speed < 0 or self.gust_std < 0:
            raise ValueError("wind_speed and gust_std must be >= 0")
        if self.move_time_limit < self.move_duration:
            raise ValueError("move_time_limit must be at least move_duration")

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
        """Hash of every field that changes a calm-air move (plus ``extra``, e.g. model XML)."""
        relevant = {k: v for k, v in asdict(self).items() if k not in _NOT_CALIBRATED}
        text = json.dumps(relevant, sort_keys=True) + extra
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    @classmethod
    def field_names(cls) -> set[str]:
        return {f.name for f in fields(cls)}
