"""The energy of one budget unit: a nominal one-cell move in calm air, measured by flying it.

The energy is what the move draws from the LiPo pack (:mod:`~cpp_mujoco.physics.power.battery`): the
rotors' electrical energy plus the pack's I²R loss, with the pack held at the middle of the
budget's state-of-charge window.

The unit depends only on how a calm move flies (airframe, controller, timing, geometry), not on
the map or the weather, so it is cached per configuration: in this process, and as a small JSON
file keyed by a hash of the configuration, the model XML, the flight code and the MuJoCo
version (written atomically, so parallel test workers never read half a file). A cache file is
trusted only if it holds its own key and a unit energy that is finite and within a plausible
factor of the airframe's hover power × the move duration; anything else is recalibrated and
rewritten — a wrong unit would silently rescale every physics budget.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import replace
from functools import cache
from pathlib import Path

import mujoco
import numpy as np

from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.action import HOVER, MOVE
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.flight import Flight
from cpp_mujoco.physics.power.rotor import PowerModel
from cpp_mujoco.physics.quadrotor import QuadrotorParams, quadrotor_xml
from cpp_mujoco.util.io import WriteError, atomic_write_text

_MEMO: dict[str, dict] = {}
# a calm one-cell move costs about hover power × move duration (≈ 1.03× for the defaults):
# outside this band the figures are not a calibration of this airframe
PLAUSIBLE_UNIT = (0.5, 4.0)
_FIGURES = ("unit_energy_j", "move_energy_min_j", "move_energy_max_j", "move_duration_s",
            "hover_power_w", "hover_energy_j")  # fmt: skip
# out and back along both axes from the middle of a 3×3 map: every heading flown once each way
_MOVES = ((1, 2), (1, 1), (0, 1), (1, 1), (1, 0), (1, 1), (2, 1), (1, 1))


def cache_dir() -> Path:
    """``$CPP_MUJOCO_CACHE`` or ``~/.cache/cpp_mujoco``."""
    root = os.environ.get("CPP_MUJOCO_CACHE") or Path.home() / ".cache" / "cpp_mujoco"
    return Path(root) / "calibration"


def calibrate(config: PhysicsConfig) -> dict:
    """Fly the calibration moves and return the figures (energy per move in J, …)."""
    # the cut-off is a limit of the pack, not part of a move's cost: it is off while measuring
    calm = replace(config, wind_speed=0.0, gust_std=0.0, turbulence="none", battery_cutoff_v=0.0)
    grid = GridMap.from_ascii(["GGG", "GGG", "GGG"], name="calibration")
    flight = Flight.alone(grid, calm)
    flight.reset(0, 1, 1, math.inf, np.random.default_rng(0))
    hover = flight.fly_one(HOVER, 4)
    moves = [flight.fly_one(MOVE, r * 3 + c) for r, c in _MOVES]
    if any(m.failure or not m.arrived for m in moves):
        raise RuntimeError(f"calibration flight failed: {moves}")
    energies = [m.energy for m in moves]
    return {
        "unit_energy_j": sum(energies) / len(energies),
        "move_energy_min_j": min(energies),
        "move_energy_max_j": max(energies),
        "move_duration_s": sum(m.duration for m in moves) / len(moves),
        "hover_power_w": hover.energy / hover.duration,
        "hover_energy_j": hover.energy,
    }


def calibration(config: PhysicsConfig) -> dict:
    """Cached :func:`calibrate` for this configuration; an invalid cache file is recalibrated."""
    extra = quadrotor_xml().read_text() + mujoco.__version__ + _source_digest()
    key = config.calibration_key(extra)
    if key in _MEMO:
        return _MEMO[key]
    path = cache_dir() / f"{key}.json"
    try:
        result = json.loads(path.read_text())
        check_calibration(result, config, key)
    except (OSError, ValueError):
        result = {"key": key, **calibrate(config)}
        check_calibration(result, config, key, fresh=True)
        try:
            atomic_write_text(path, json.dumps(result, indent=1))
        except WriteError:
            pass  # a read-only cache only costs a re-calibration next time
    _MEMO[key] = result
    return result


def check_calibration(data: object, config: PhysicsConfig, key: str, fresh: bool = False) -> None:
    """Raise ``ValueError`` unless ``data`` is a calibration of ``config`` under ``key``.

    A freshly flown calibration that fails is a broken flight model: ``RuntimeError``.
    """
    try:
        if not isinstance(data, dict) or data.get("key") != key:
            raise ValueError("the cache file is not a calibration for this configuration")
        for name in _FIGURES:
            value = data.get(name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{name} is {value!r}, not a number")
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} is {value!r}, not a finite positive number")
        expected = hover_power(config) * config.move_duration
        lo, hi = PLAUSIBLE_UNIT
        if not lo * expected <= data["unit_energy_j"] <= hi * expected:
            raise ValueError(
                f"unit_energy_j {data['unit_energy_j']:.6g} J is outside {lo}..{hi} × hover "
                f"power × move duration ({expected:.6g} J)"
            )
        if not data["move_energy_min_j"] <= data["unit_energy_j"] <= data["move_energy_max_j"]:
            raise ValueError("unit_energy_j is not between move_energy_min_j and _max_j")
    except ValueError as e:
        if fresh:
            raise RuntimeError(f"implausible calibration flight: {e}") from None
        raise


def hover_power(config: PhysicsConfig) -> float:
    """W the airframe draws to hover in ``config``'s air (momentum theory, no flight needed)."""
    params = _airframe()
    return PowerModel(params, config.air_density).power([params.weight / 4] * 4)


@cache
def _airframe() -> QuadrotorParams:
    model = mujoco.MjModel.from_xml_path(str(quadrotor_xml()))
    return QuadrotorParams.from_model(model, prefix="")


def unit_energy(config: PhysicsConfig) -> float:
    """J in one budget unit: the calibrated calm-air move times (1 + ``unit_margin``)."""
    return float(calibration(config)["unit_energy_j"]) * (1.0 + config.unit_margin)


# the modules and folders whose code flies a calibration move
FLIGHT_SOURCES = (
    "flight.py", "tick.py", "action.py", "airborne.py", "arena.py", "quadrotor.py",
    "geometry.py", "config.py", "kernel_constants.py", "tick_kernels.py",
)  # fmt: skip
FLIGHT_PARTS = ("control", "air", "power", "sensing")


def _source_digest() -> str:
    """The code that flies a move: a change to it must invalidate cached units (``config.py``
    too: default gains are left out of the key, their values are in its source)."""
    here = Path(__file__).resolve().parent
    parts = [here / n for n in FLIGHT_SOURCES]
    parts += sorted(f for d in FLIGHT_PARTS for f in (here / d).glob("*.py"))
    return "".join(f.read_text() for f in parts)
