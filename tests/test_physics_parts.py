"""The flight's swappable parts (controller, wind) as array-level protocols, controller gains
from the config, and the one cell ↔ world conversion every physics part goes through."""

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.action import HOVER, LAND, MOVE
from cpp_mujoco.physics.air.wind import Wind
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.config import ControllerGains, PhysicsConfig
from cpp_mujoco.physics.control.controller import GeometricController
from cpp_mujoco.physics.flight import Flight
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.physics.parts import Controller, WindModel
from cpp_mujoco.physics.quadrotor import QuadrotorParams
from cpp_mujoco.physics.sensing.camera import CoverageCamera, corner_rays
from cpp_mujoco.physics.view.scenery import Scenery

OPEN = GridMap.from_ascii(["TTT", "TLT", "TTT"], name="open3")
GUSTY = PhysicsConfig(wind_speed=5.0, wind_direction=60.0, gust_std=1.5, turbulence="light")


@pytest.fixture(scope="module")
def model():
    return compile_arena(build_arena(OPEN, PhysicsConfig()))


def flight_of(model, config, **parts) -> Flight:
    return Flight(model, OPEN, config, 1, np.zeros((1, OPEN.target.size), bool), **parts)


def fly(flight: Flight, seed: int = 3) -> list:
    """East, a rejected-style hover, back west, land: every macro-step kind once."""
    flight.reset(0, 1, 1, math.inf, np.random.default_rng(seed))
    results = [flight.fly_one(kind, cell) for kind, cell in ((MOVE, 5), (HOVER, 5), (MOVE, 4),
                                                               (LAND, 4))]  # fmt: skip
    return results + [flight.state[0].tolist()]


def test_the_built_in_parts_called_as_parts_fly_what_the_fused_tick_flies(model):
    """The built-in controller and wind handed in as parts are called through the array
    protocols from Python, not fused into the tick: the same flight, to the double."""
    params = QuadrotorParams.from_model(model)
    controller = GeometricController(params, GUSTY.controller)
    wind = Wind(GUSTY, GUSTY.control_dt)
    assert isinstance(controller, Controller) and isinstance(wind, WindModel)
    explicit = flight_of(model, GUSTY, controller=controller, wind=wind)
    assert explicit.controller is controller and explicit.wind is wind
    assert explicit._tick.given == 3  # both come from Python
    default = fly(flight_of(model, GUSTY))
    assert fly(explicit) == default  # every ActionResult field and the final state, exactly
    assert default[3].landed and default[0].energy > 0


class RecordedWind:
    """A user's wind part: a fixed vector, remembering when and where it was asked."""

    def __init__(self, vector):
        self.vector, self.calls, self.resets = np.array(vector), [], 0

    def reset(self, i, rng):
        self.resets += 1

    def velocity(self, drones, time, position):
        self.calls.append((time.copy(), position.copy()))
        return np.tile(self.vector, (len(drones), 1))


def test_a_custom_wind_part_is_honoured(model):
    windy = PhysicsConfig(wind_speed=6.0, wind_direction=90.0)  # from the east
    part = RecordedWind(windy.wind_vector)
    calm_config = PhysicsConfig()
    with_part = flight_of(model, calm_config, wind=part)
    with_part.reset(0, 1, 1, math.inf, np.random.default_rng(0))
    result = with_part.fly_one(MOVE, 5)  # east, into the wind the part blows
    # the same flight as the config's own steady wind of that vector
    reference = flight_of(model, windy)
    reference.reset(0, 1, 1, math.inf, np.random.default_rng(0))
    assert result == reference.fly_one(MOVE, 5)
    calm = flight_of(model, calm_config)
    calm.reset(0, 1, 1, math.inf, np.random.default_rng(0))
    assert abs(result.energy / calm.fly_one(MOVE, 5).energy - 1) > 0.005  # not the calm flight
    ticks = round(result.duration / calm_config.control_dt)
    assert part.resets == 1 and len(part.calls) == ticks  # one call per control tick
    times = [float(t[0]) for t, _ in part.calls]
    assert times == sorted(times) and part.calls[0][1].shape == (1, 3)
    assert np.array_equal(with_part.wind_now[0], windy.wind_vector)


class HoverOnly:
    """A user's controller part that ignores the reference: hover thrust on every rotor."""

    lead = 0.1

    def __init__(self, thrust):
        self.thrust, self.calls = thrust, 0

    def reset(self, i):
        pass

    def hover_thrust(self):
        return self.thrust

    def __call__(self, drones, pos, vel, R, omega, thrust, ref, dt):
        self.calls += 1
        assert R.shape == (len(drones), 3, 3) and ref.shape == (len(drones), 3, 3)
        return np.full((len(drones), 4), self.thrust)


def test_a_custom_controller_part_flies_the_drone(model):
    """A controller that never tilts cannot follow a move: the drone stays over its start
    until the move's time limit ends the action (the flight's rules hold for any part)."""
    params = QuadrotorParams.from_model(model)
    part = HoverOnly(params.weight / 4)
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=OPEN, controller_model=part).unwrapped
    assert env.flight.controller is part
    env.reset(seed=0, options={"start": (1, 1), "budget": 20})
    start = env.flight.position(0)
    result = env.flight.fly_one(MOVE, 5)
    assert part.calls > 10 and not result.arrived and result.failure is None
    assert result.duration == pytest.approx(env.config.move_time_limit, abs=env.config.control_dt)
    assert np.linalg.norm(env.flight.position(0)[:2] - start[:2]) < 0.05
    assert result.tracking_error == pytest.approx(env.config.cell_size, abs=0.05)
    with pytest.raises(TypeError, match="controller_model must implement"):
        gym.make("cpp_mujoco/MuJoCo-v0", map=OPEN, controller_model=object())
    with pytest.raises(TypeError, match="wind_model must implement"):
        gym.make("cpp_mujoco/MuJoCo-v0", map=OPEN, wind_model=lambda t: (0, 0, 0))


def test_parts_are_options_of_the_vector_env(model):
    windy = PhysicsConfig(wind_speed=6.0, wind_direction=90.0)
    env = gym.make_vec("cpp_mujoco/MuJoCo-v0", num_envs=2, map=OPEN,
                       wind_model=RecordedWind(windy.wind_vector))  # fmt: skip
    reference = gym.make_vec("cpp_mujoco/MuJoCo-v0", num_envs=2, map=OPEN, wind_speed=6.0,
                             wind_direction=90.0)  # fmt: skip
    outs = []
    for e in (env, reference):
        e.reset(seed=5)
        outs.append([e.step(np.array([1, 3]))[1].tolist() for _ in range(2)])
        outs[-1].append(e.unwrapped.flight.state.tolist())
    assert outs[0] == outs[1]


def test_controller_gains_from_the_config_reach_the_controller(model):
    slow = PhysicsConfig(controller=ControllerGains(position_bw=1.0, feedforward_lead=0.05))
    flight = flight_of(model, slow)
    assert flight.law.kx == pytest.approx(flight.params.mass * 1.0**2)
    assert flight.controller.lead == 0.05 and flight.refs.lead == 0.05
    default = flight_of(model, PhysicsConfig())
    traces = []
    for f in (flight, default):
        f.reset(0, 1, 1, math.inf, np.random.default_rng(0))
        f.trace = []
        assert f.fly_one(MOVE, 5).arrived
        traces.append(f.trace)
    lag = [abs(p[1] - q[1]) for p, q in zip(*traces, strict=False)]
    assert max(lag) > 0.05  # a softer position loop flies a visibly different path
    # a controller part wins over the config's gains
    part = GeometricController(flight.params, ControllerGains())
    assert flight_of(model, slow, controller=part).controller is part


def test_gains_are_options_of_the_env_and_part_of_the_calibration_key(tmp_path, monkeypatch):
    from cpp_mujoco.physics import calibration as cal

    monkeypatch.setenv("CPP_MUJOCO_CACHE", str(tmp_path))
    monkeypatch.setattr(cal, "_MEMO", {})
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=OPEN, controller={"attitude_bw": 10.0}).unwrapped
    assert env.config.controller == ControllerGains(attitude_bw=10.0)
    assert env.flight.law.gains == env.config.controller
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
    flight = Flight.alone(grid_map, config)
    tiles = Scenery.from_model(flight.model).tiles()[0]  # the drawn map, as the model stores it
    centers = geo.centers()
    for cell, (x, y) in enumerate(centers):
        row, col = divmod(cell, geo.width)
        assert geo.cell_center(row, col) == (x, y)
        assert geo.cell_of(x, y) == (row, col) and geo.cell_index(x, y) == cell
        assert tuple(tiles[cell, :2]) == (x, y)
        assert flight.waypoint(cell)[:2] == (x, y)
    assert geo.cell_index(-7.6, 0.0) is None and geo.cell_index(0.0, 4.6) is None


def seen_by_hand(pos, mat, rays, centers, half, cos_max_tilt, min_down=0.05):
    """The camera's rule written out: the corner rays cast to z = 0, a cell seen when its
    centre is inside the quadrilateral and within ``half`` of the camera in x and y."""
    if pos[2] <= 0 or mat[2, 2] < cos_max_tilt:
        return set()
    world = rays @ mat.T  # each ray in world axes
    if np.any(-world[:, 2] < min_down):
        return set()
    ground = pos[:2] + world[:, :2] * (pos[2] / -world[:, 2])[:, None]
    seen = set()
    for cell, (x, y) in enumerate(centers):
        edges = np.roll(ground, 1, axis=0)
        cross = (ground[:, 0] - edges[:, 0]) * (y - edges[:, 1]) - (ground[:, 1] - edges[:, 1]) * (
            x - edges[:, 0]
        )
        inside = not (np.any(cross > 0) and np.any(cross < 0))
        if inside and abs(x - pos[0]) <= half and abs(y - pos[1]) <= half:
            seen.add(cell)
    return seen


def test_the_camera_kernel_sees_what_the_rule_says():
    """Random camera poses over an odd map (tilted up to 50°: some past the frame tilt limit,
    some so low that their footprint holds no cell centre): the compiled frame marks exactly
    the cells the rule written out by hand sees."""
    grid_map = GridMap.from_ascii(["TTTTTTT", "TLTNTTT", "TTTTTTT", "GGTTTTT"], name="odd")
    config = PhysicsConfig(cell_size=3.0, altitude=4.5)
    model = compile_arena(build_arena(grid_map, config))
    geo, n, ncam = GridGeometry.of(grid_map, config.cell_size), 300, model.ncam
    xpos, xmat = np.zeros((n, ncam, 3)), np.zeros((n, ncam, 9))
    coverage = np.zeros((n, grid_map.target.size), bool)
    camera = CoverageCamera(model, xpos, xmat, np.zeros(n), geo, config, grid_map.target, coverage)
    rng = np.random.default_rng(0)
    half_x, half_y = geo.half_extent
    poses = []
    for d in range(n):
        pos = np.array([*rng.uniform([-half_x, -half_y], [half_x, half_y]), rng.uniform(2, 7)])
        axis = rng.normal(size=3)
        quat = np.zeros(4)
        mujoco.mju_axisAngle2Quat(quat, axis / np.linalg.norm(axis), rng.uniform(0, 0.87))
        mat = np.zeros(9)  # a camera looks along its −z: unrotated, it looks straight down
        mujoco.mju_quat2Mat(mat, quat)
        xpos[d, camera.cam_id], xmat[d, camera.cam_id] = pos, mat
        poses.append((pos, mat.reshape(3, 3)))
    newly = camera.capture(np.arange(n))
    rays = np.array(corner_rays(float(model.cam_fovy[camera.cam_id])))
    centers = geo.centers()
    targets = set(np.flatnonzero(grid_map.target.reshape(-1)).tolist())
    kinds = set()
    for d, (pos, mat) in enumerate(poses):
        expected = seen_by_hand(pos, mat, rays, centers, camera.nominal_half, camera.cos_max_tilt)
        assert set(np.flatnonzero(coverage[d]).tolist()) == expected, d
        assert newly[d] == len(expected & targets)
        kinds.add("tilted" if mat[2, 2] < camera.cos_max_tilt else len(expected) > 0)
    assert {"tilted", True} <= kinds  # frames that see, frames too tilted to be used


def test_the_worked_example_of_a_user_wind_flies():
    """docs/physics.md's gust front, run as written: the move starts ahead of the front in
    calm air and ends behind it in the westerly, which costs energy a calm move does not."""
    from pathlib import Path

    page = (Path(__file__).resolve().parents[1] / "docs" / "physics.md").read_text()
    block = page.split("**A user's wind, worked example**", 1)[1]
    code = block.split("```python\n", 1)[1].split("```", 1)[0]
    scope: dict = {}
    exec(compile(code, "docs/physics.md", "exec"), scope)  # noqa: S102 - the page's own example
    env, info = scope["env"], scope["info"]
    flight = env.unwrapped.flight
    assert info["crash_reason"] is None and not scope["terminated"]
    assert flight.wind_now[0].tolist() == [10.0, 0.0, 0.0]  # behind the front at the end
    calm = gym.make("cpp_mujoco/MuJoCo-v0", map="A")
    calm.reset(seed=0, options={"start": (12, 0), "budget": 40})
    calm_info = calm.step(1)[4]
    assert info["energy_used_j"] > 1.05 * calm_info["energy_used_j"]
