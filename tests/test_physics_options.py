"""Physics options are validated at the door, and the calibration cache is trusted only if valid."""

import json
import math

import gymnasium as gym
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics import calibration as cal
from cpp_mujoco.physics.config import PhysicsConfig

SMALL = GridMap.from_ascii(["LTT", "TNT", "TTL"], name="small")
NAN, INF = float("nan"), float("inf")

BAD = [
    ("wind_speed", NAN), ("wind_speed", INF), ("wind_speed", -1.0), ("wind_speed", True),
    ("wind_direction", NAN), ("wind_direction", -INF), ("wind_direction", "north"),
    ("gust_std", NAN), ("gust_std", -0.5),
    ("gust_tau", 0.0), ("gust_tau", -2.0), ("gust_tau", NAN),
    ("air_density", 0.0), ("air_density", -1.2), ("air_density", INF),
    ("timestep", 0.0), ("timestep", -0.004), ("timestep", NAN), ("timestep", 0.5),
    ("timestep", 0.003),  # 50 Hz control is not a whole number of 3 ms steps
    ("control_rate", 0.0), ("camera_rate", -10.0),
    ("cell_size", 0.0), ("cell_size", "4"), ("altitude", -6.0), ("altitude", NAN),
    ("move_duration", 0.0), ("move_time_limit", 1.0),  # shorter than move_duration
    ("land_time_limit", 1.0),  # shorter than land_duration
    ("unit_margin", -0.01), ("unit_margin", 0.5),
    ("max_tilt_deg", 200.0), ("max_frame_tilt_deg", 0.0), ("max_tracking_error", NAN),
]  # fmt: skip


@pytest.mark.parametrize(("field", "value"), BAD, ids=[f"{f}={v!r}" for f, v in BAD])
def test_bad_physics_option_is_a_value_error_naming_it(field, value):
    with pytest.raises(ValueError, match=field):
        gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL, **{field: value})


def test_good_values_are_kept_as_floats_and_hash_alike():
    config = PhysicsConfig(cell_size=4, wind_direction=-450.0, gust_std=np.float32(0.5))
    assert type(config.cell_size) is float and type(config.gust_std) is float
    assert PhysicsConfig(cell_size=4).calibration_key() == PhysicsConfig().calibration_key()


# ----------------------------------------------------------------------------- calibration cache
@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    """One real calibration flight of the default configuration (its figures and file text)."""
    mp = pytest.MonkeyPatch()
    mp.setenv("CPP_MUJOCO_CACHE", str(tmp_path_factory.mktemp("cache")))
    mp.setattr(cal, "_MEMO", {})
    figures = cal.calibration(PhysicsConfig())
    (path,) = (cal.cache_dir()).glob("*.json")
    text = path.read_text()
    mp.undo()
    return figures, path.name, text


@pytest.fixture
def cache(tmp_path, monkeypatch, flown):
    """A fresh cache folder holding a copy of a valid file; ``calibrate`` counts its calls."""
    figures, name, text = flown
    monkeypatch.setenv("CPP_MUJOCO_CACHE", str(tmp_path))
    monkeypatch.setattr(cal, "_MEMO", {})
    calls = []
    measured = {k: v for k, v in figures.items() if k != "key"}
    monkeypatch.setattr(cal, "calibrate", lambda c: calls.append(c) or dict(measured))
    path = tmp_path / "calibration" / name
    path.parent.mkdir()
    path.write_text(text)
    return path, json.loads(text), calls


def test_a_valid_cache_is_read_without_flying(cache):
    path, data, calls = cache
    assert cal.calibration(PhysicsConfig()) == data
    assert calls == [] and data["key"] == path.stem


def _corrupt(data: dict, **changes) -> str:
    return json.dumps({**data, **changes})


CORRUPT = {
    "empty object": lambda d: "{}",
    "zero unit": lambda d: _corrupt(d, unit_energy_j=0),
    "negative unit": lambda d: _corrupt(d, unit_energy_j=-d["unit_energy_j"]),
    "NaN unit": lambda d: _corrupt(d, unit_energy_j=math.nan),  # json's NaN token
    "NaN as a string": lambda d: _corrupt(d, unit_energy_j="NaN"),
    "null unit": lambda d: _corrupt(d, unit_energy_j=None),
    "missing hover power": lambda d: json.dumps(
        {k: v for k, v in d.items() if k != "hover_power_w"}
    ),
    "implausible unit": lambda d: _corrupt(
        d, unit_energy_j=d["unit_energy_j"] * 100, move_energy_min_j=1.0, move_energy_max_j=1e9
    ),
    "another config's key": lambda d: _corrupt(d, key="0123456789abcdef"),
    "truncated": lambda d: json.dumps(d)[: len(json.dumps(d)) // 2],
    "not an object": lambda d: "[485.2]",
}


@pytest.mark.parametrize("kind", list(CORRUPT))
def test_an_invalid_cache_is_recalibrated_and_rewritten(cache, kind):
    path, data, calls = cache
    path.write_text(CORRUPT[kind](data))
    result = cal.calibration(PhysicsConfig())
    assert len(calls) == 1, "an invalid cache must not be trusted"
    assert result == data
    assert json.loads(path.read_text()) == data  # rewritten valid
    assert cal.unit_energy(PhysicsConfig()) == pytest.approx(data["unit_energy_j"] * 1.02)
    assert list(path.parent.iterdir()) == [path]  # no temporary file left behind


def test_an_implausible_fresh_calibration_is_an_error(cache, monkeypatch):
    path, data, _ = cache
    path.unlink()
    broken = {k: v for k, v in data.items() if k != "key"} | {"unit_energy_j": 1e-3}
    monkeypatch.setattr(cal, "calibrate", lambda c: dict(broken))
    with pytest.raises(RuntimeError, match="implausible calibration"):
        cal.calibration(PhysicsConfig())
    assert not path.exists()
