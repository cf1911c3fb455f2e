"""The energy of one budget unit: a nominal one-cell move in calm air, measured by flying it.

The unit depends only on how a calm move flies (airframe, controller, timing, geometry), not on
the map or the weather, so it is cached per configuration: in this process, and as a small JSON
file keyed by a hash of the configuration, the model XML, the flight code and the MuJoCo
version (written
atomically, so parallel test workers never read half a file).
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import replace
from pathlib import Path

import mujoco

from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.flight import Flight
from cpp_mujoco.physics.quadrotor import quadrotor_xml

_MEMO: dict[str, dict] = {}
# out and back along both axes from the middle of a 3×3 map: every heading flown once each way
_MOVES = ((1, 2), (1, 1), (0, 1), (1, 1), (1, 0), (1, 1), (2, 1), (1, 1))


def cache_dir() -> Path:
    """``$CPP_MUJOCO_CACHE`` or ``~/.cache/cpp_mujoco``."""
    root = os.environ.get("CPP_MUJOCO_CACHE") or Path.home() / ".cache" / "cpp_mujoco"
    return Path(root) / "calibration"


def calibrate(config: PhysicsConfig) -> dict:
    """Fly the calibration moves and return the figures (energy per move in J, …)."""
    calm = replace(config, wind_speed=0.0, gust_std=0.0)
    grid = GridMap.from_ascii(["GGG", "GGG", "GGG"], name="calibration")
    flight = Flight(compile_arena(build_arena(grid, calm)), grid, calm)
    flight.reset(1, 1)
    hover = flight.hover(4)
    moves = [flight.move(r * 3 + c) for r, c in _MOVES]
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
    """Cached :func:`calibrate` for this configuration."""
    extra = quadrotor_xml().read_text() + mujoco.__version__ + _source_digest()
    key = config.calibration_key(extra)
    if key in _MEMO:
        return _MEMO[key]
    path = cache_dir() / f"{key}.json"
    try:
        result = json.loads(path.read_text())
    except (OSError, ValueError):
        result = calibrate(config)
        _write_atomic(path, result)
    _MEMO[key] = result
    return result


def unit_energy(config: PhysicsConfig) -> float:
    """J in one budget unit: the calibrated calm-air move times (1 + ``unit_margin``)."""
    return float(calibration(config)["unit_energy_j"]) * (1.0 + config.unit_margin)


def _source_digest() -> str:
    """The code that flies a move: a change to it must invalidate cached units."""
    here = Path(__file__).resolve().parent
    names = ("controller.py", "flight.py", "energy.py", "wind.py", "arena.py", "quadrotor.py")
    return "".join((here / n).read_text() for n in names)


def _write_atomic(path: Path, data: dict) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "w") as fh:
            json.dump(data, fh, indent=1)
        os.replace(tmp, path)
    except OSError:
        pass  # a read-only home only costs a re-calibration next time
