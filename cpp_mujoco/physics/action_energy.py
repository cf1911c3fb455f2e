"""What one grid action costs in wind: a move upwind, downwind and across it, a hover, a landing.

Why measure it by flying: the cost of an action is the battery energy of a MuJoCo macro-step,
which depends on the airspeed through the rotors (forward-flight power), the drag the controller
tilts against, the pack's loss and, in turbulence, on the gusts met on the way. The figures are
flown on an open 5×5 map from its middle cell: a settling hover first (the external-force
observer converges), then out and back along each axis — every heading flown once from the
middle and once back to it — then a hover and a landing. A heading is *upwind* when it points
where the wind blows from, *downwind* opposite, *crosswind* otherwise (the two averaged).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.action import HOVER, LAND, MOVE
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.flight import Flight

_OPEN = GridMap.from_ascii(["TTTTT", "TTTTT", "TTLTT", "TTTTT", "TTTTT"], name="open-5x5")
# heading (deg, clockwise from north) → the neighbour of the middle cell (row, col)
_HEADINGS = {0.0: (1, 2), 90.0: (2, 3), 180.0: (3, 2), 270.0: (2, 1)}
KINDS = ("upwind", "downwind", "crosswind", "hover", "land")


@dataclass(frozen=True)
class ActionEnergy:
    """Mean battery energy (J) of each kind of action in one weather, and its spread."""

    wind_speed: float
    wind_direction: float
    turbulence: str
    mean_j: dict[str, float]  # kind → mean J
    std_j: dict[str, float]  # kind → standard deviation over the samples (0 in steady wind)
    samples: dict[str, int]  # kind → how many actions were flown


def _kind(heading: float, wind_from: float) -> str:
    offset = (heading - wind_from) % 360.0
    return "upwind" if offset == 0.0 else "downwind" if offset == 180.0 else "crosswind"


def flown_sequence(config: PhysicsConfig, seed: int = 0, flight: Flight | None = None):
    """One flight of the sequence in ``config``'s weather (gusts drawn from ``seed``):
    ``[(kind, joules), …]`` in the order flown, the settling hover left out. In calm air every
    heading counts as crosswind (no wind to face)."""
    flight = flight or Flight.alone(_OPEN, config)
    calm = config.wind_speed == 0.0
    width = _OPEN.shape[1]
    middle = 2 * width + 2
    flight.reset(0, 2, 2, math.inf, np.random.default_rng(seed))
    flight.fly_one(HOVER, middle)  # settle
    sequence: list[tuple[str, float]] = []
    for heading, (row, col) in _HEADINGS.items():
        out, back = flight.fly_one(MOVE, row * width + col), flight.fly_one(MOVE, middle)
        for h, result in ((heading, out), ((heading + 180.0) % 360.0, back)):
            _check(result, f"move heading {h:g}°")
            kind = "crosswind" if calm else _kind(h, config.wind_direction % 360.0)
            sequence.append((kind, result.energy))
    sequence.append(("hover", _check(flight.fly_one(HOVER, middle), "hover").energy))
    sequence.append(("land", _check(flight.fly_one(LAND, middle), "landing").energy))
    return sequence


def action_energy(config: PhysicsConfig, repeats: int = 1, seed: int = 0) -> ActionEnergy:
    """Fly the sequence ``repeats`` times (seeds ``seed``, ``seed + 1`` …: different gusts) in
    ``config``'s weather."""
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    flight = Flight.alone(_OPEN, config)
    energies: dict[str, list[float]] = {k: [] for k in KINDS}
    for r in range(repeats):
        for kind, joules in flown_sequence(config, seed + r, flight):
            energies[kind].append(joules)
    present = {k: v for k, v in energies.items() if v}
    return ActionEnergy(
        wind_speed=config.wind_speed,
        wind_direction=config.wind_direction,
        turbulence=config.turbulence,
        mean_j={k: float(np.mean(v)) for k, v in present.items()},
        std_j={k: float(np.std(v)) for k, v in present.items()},
        samples={k: len(v) for k, v in present.items()},
    )


def _check(result, what: str):
    if result.failure is not None:
        raise RuntimeError(f"{what} failed while measuring action energies: {result.failure}")
    return result


def weathers(
    base: PhysicsConfig,
    speeds: tuple[float, ...],
    directions: tuple[float, ...],
    turbulence: str,
):
    """``base`` in calm air and at every speed × direction (one calm config: in calm air the
    direction means nothing), with ``turbulence`` above 0 m/s."""
    for speed in speeds:
        for direction in directions if speed > 0 else (0.0,):
            yield replace(
                base,
                wind_speed=speed,
                wind_direction=direction,
                turbulence=turbulence if speed > 0 else "none",
            )


def action_energy_table(
    base: PhysicsConfig,
    speeds: tuple[float, ...] = (0.0, 3.0, 6.0, 9.0, 12.0),
    directions: tuple[float, ...] = (0.0, 90.0, 180.0, 270.0),
    turbulence: str = "none",
    repeats: int = 1,
) -> list[ActionEnergy]:
    """:func:`action_energy` for calm air and every speed × direction."""
    return [
        action_energy(config, repeats) for config in weathers(base, speeds, directions, turbulence)
    ]
