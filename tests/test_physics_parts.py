"""The flight's swappable parts (controller, wind), controller gains from the config, and the one
cell ↔ world conversion every physics part goes through."""

import math

import gymnasium as gym
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.air.wind import Wind
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.config import ControllerGains, PhysicsConfig
from cpp_mujoco.physics.control.controller import GeometricController
from cpp_mujoco.physics.flight import Flight
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.physics.parts import Controller, WindModel
from cpp_mujoco.physics.quadrotor import QuadrotorParams
from cpp_mujoco.physics.sensing.camera import cells_in_footprint, inside_polygon
from cpp_mujoco.review.scenery import Scenery

OPEN = GridMap.from_ascii(["TTT", "TLT", "TTT"], name="open3")
GUSTY = PhysicsConfig(wind_speed=5.0, wind_direction=60.0, gust_std=1.5)


@pytest.fixture(scope="module")
def model():
    return compile_arena(build_arena(OPEN, PhysicsConfig()))


def fly(flight: Flight, seed: int = 3) -> list:
    """East, a rejected-style hover, back west, land: every macro-step kind once."""
    flight.reset(1, 1, rng=np.random.default_rng(seed))
    results = [flight.move(5), flight.hover(5), flight.move(4), flight.land(4)]
    return results + [flight.position.tolist(), flight.data.qvel.tolist()]


def test_explicit_default_parts_fly_identically_to_the_defaults(model):
    params = QuadrotorParams.from_model(model)
    controller = GeometricController(params, GUSTY.controller)
    wind = Wind(GUSTY, GUSTY.control_dt)
    assert isinstance(controller, Controller) and isinstance(wind, WindModel)
    explicit = Flight(model, OPEN, GUSTY, controller=controller, wind=wind)
    assert explicit.controller is controller and explicit.wind is wind
    default = fly(Flight(model, OPEN, GUSTY))
    assert fly(explicit) == default  # every ActionResult field and the final state, exactly
    assert default[3].landed and default[0].energy > 0


class RecordedWind:
    """A wind part: a fixed vector, remembering when and where it was asked."""

    def __init__(self, vector):
        self.vector, self.calls, self.resets = tuple(vector), [], 0

    def reset(self, rng):
        self.resets += 1

    def velocity(self, time, position):
        self.calls.append((time, tuple(position)))
        return self.vector


def test_a_custom_wind_part_is_honoured(model):
    windy = PhysicsConfig(wind_speed=6.0, wind_direction=90.0)  # from the east
    part = RecordedWind(windy.wind_vector)
    calm_config = PhysicsConfig()
    with_part = Flight(model, OPEN, calm_config, wind=part)
    with_part.reset(1, 1)
    result = with_part.move(5)  # east, into the wind the part blows
    # the same flight as the config's own steady wind of that vector
    reference = Flight(model, OPEN, windy)
    reference.reset(1, 1)
    assert result == reference.move(5)
    calm = Flight(model, OPEN, calm_config)
    calm.reset(1, 1)
    assert abs(result.energy / calm.move(5).energy - 1) > 0.005  # and not the calm flight
    ticks = round(result.duration / calm_config.control_dt)
    assert part.resets == 2 and len(part.calls) == ticks  # reset + one call per control update
    times = [t for t, _ in part.calls]
    assert times == sorted(times) and len(part.calls[0][1]) == 3


def test_controller_gains_from_the_config_reach_the_controller(model):
    slow = PhysicsConfig(controller=ControllerGains(position_bw=1.0, feedforward_lead=0.05))
    flight = Flight(model, OPEN, slow)
    assert flight.controller.kx == pytest.approx(flight.params.mass * 1.0**2)
    assert flight.controller.lead == 0.05
    flight.reset(1, 1)
    flight.trace = []
    default = Flight(model, OPEN, PhysicsConfig())
    default.reset(1, 1)
    default.trace = []
    a, b = flight.move(5), default.move(5)
    assert a.arrived and b.arrived
    lag = [abs(p[1] - q[1]) for p, q in zip(flight.trace, default.trace, strict=False)]
    assert max(lag) > 0.05  # a softer position loop flies a visibly different path
    # a custom controller part wins over the config's gains
    part = GeometricController(flight.params, ControllerGains())
    assert Flight(model, OPEN, slow, controller=part).controller is part


def test_gains_are_options_of_the_env_and_part_of_the_calibration_key(tmp_path, monkeypatch):
    from cpp_mujoco.physics import calibration as cal

    monkeypatch.setenv("CPP_MUJOCO_CACHE", str(tmp_path))
    monkeypatch.setattr(cal, "_MEMO", {})
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=OPEN, controller={"attitude_bw": 10.0}).unwrapped
    assert env.config.controller == ControllerGains(attitude_bw=10.0)
    assert env.flight.controller.c.gains == env.config.controller
    default_key = PhysicsConfig().calibration_key()
    assert env.config.calibration_key() != default_key
    assert env.unit_energy != pytest.approx(cal.unit_energy(PhysicsConfig()), rel=1e-9)
    # default gains leave the key of a default configuration what it was before they existed
    assert PhysicsConfig(controller=ControllerGains()).calibration_key() == default_key
    assert default_key == "d92c73dafaa04d77"


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ({"position_bandwidth": 3.0}, r"controller: unknown gain\(s\) \['position_bandwidth'\]"),
        ({"position_bw": -1.0}, "controller.position_bw must be a finite number > 0"),
        ({"tilt_limit_deg": 90.0}, r"controller.tilt_limit_deg must be in \(0, 90\)"),
        ({"observer_tau": float("nan")}, "controller.observer_tau must be"),
        (3.0, "controller must be ControllerGains or a dict"),
    ],
)
def test_bad_gains_are_one_line_errors_naming_the_gain(value, message):
    with pytest.raises(ValueError, match=message):
        PhysicsConfig(controller=value)


# ----------------------------------------------------------------------------- cell ↔ world
def test_arena_flight_and_camera_agree_with_the_one_geometry():
    """An odd, non-square map and a cell size that is not a power of two."""
    grid_map = GridMap.from_ascii(["TTTTT", "TLTNT", "TTTTT"], name="odd")
    config = PhysicsConfig(cell_size=3.0, altitude=4.5)
    geo = GridGeometry.of(grid_map, config.cell_size)
    model = compile_arena(build_arena(grid_map, config))
    flight = Flight(model, grid_map, config)
    tiles = Scenery.from_model(model).tiles()[0]  # the drawn map, as the model stores it
    centers = geo.centers()
    for cell, (x, y) in enumerate(centers):
        row, col = divmod(cell, geo.width)
        assert geo.cell_center(row, col) == (x, y)
        assert geo.cell_of(x, y) == (row, col) and geo.cell_index(x, y) == cell
        assert tuple(tiles[cell, :2]) == (x, y)
        assert flight.waypoint(cell)[:2] == (x, y)
    assert geo.cell_index(-7.6, 0.0) is None and geo.cell_index(0.0, 4.6) is None
    rng = np.random.default_rng(0)
    for _ in range(200):  # footprint candidates: exactly the centres inside the polygon
        cx, cy, r = *rng.uniform(-8, 8, 2), rng.uniform(1, 6)
        angles = np.sort(rng.uniform(0, 2 * math.pi, 4))
        poly = [(cx + r * math.cos(a), cy + r * math.sin(a)) for a in angles]
        brute = [c for c, (x, y) in enumerate(centers) if inside_polygon(poly, x, y)]
        assert cells_in_footprint(poly, geo) == brute
