"""The quadrotor model, the arena and the pure geometry/energy pieces of the physics backend."""

import math

import mujoco
import numpy as np
import pytest

from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.physics.air.wind import QuadraticDrag, Wind

# dm_control's mjcf as the arena imports it (without dm_control's headless GLFW warning)
from cpp_mujoco.physics.arena import GridGeometry, build_arena, camera_fovy, compile_arena, mjcf
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.flight import Flight
from cpp_mujoco.physics.power.rotor import IntervalEnergy, PowerModel
from cpp_mujoco.physics.quadrotor import QuadrotorParams, quadrotor_xml
from cpp_mujoco.physics.sensing.camera import (
    cells_in_footprint,
    corner_rays,
    footprint,
    inside_polygon,
)
from cpp_mujoco.review.scenery import Scenery

CONFIG = PhysicsConfig()


@pytest.fixture(scope="module")
def model():
    return compile_arena(build_arena(load_map("A"), CONFIG))


@pytest.fixture(scope="module")
def params(model):
    return QuadrotorParams.from_model(model)


def test_mujoco_dm_control_pin_builds_and_steps():
    root = mjcf.RootElement(model="tiny")
    body = root.worldbody.add("body", name="ball", pos=(0, 0, 1))
    body.add("freejoint")
    body.add("geom", type="sphere", size=(0.1,), mass=1.0)
    physics = mjcf.Physics.from_mjcf_model(root)
    for _ in range(100):
        physics.step()
    assert physics.data.time == pytest.approx(100 * physics.model.opt.timestep)
    assert physics.named.data.xpos["ball"][2] < 1.0  # it fell


def test_arena_compiles_through_dm_control():
    arena = build_arena(GridMap.from_ascii(["LTN", "..Y"]), CONFIG)
    physics = mjcf.Physics.from_mjcf_model(arena)
    physics.step()
    names = [physics.model.id2name(i, "geom") for i in range(physics.model.ngeom)]
    assert {"ground", "quadrotor/skid_l", "quadrotor/skid_r"} <= set(names)


def test_the_model_holds_only_the_ground_and_the_quadrotor(model):
    """Tiles and no-fly volumes are render-time scenery (review/scenery.py), not model geoms:
    as geoms they cost ~40 % of every mj_step."""
    quad = mujoco.MjModel.from_xml_path(str(quadrotor_xml()))
    quad_geoms = ["quadrotor/" + quad.geom(i).name for i in range(quad.ngeom)]
    names = [model.geom(i).name for i in range(model.ngeom)]
    assert names == ["ground", *quad_geoms] and model.ngeom == 1 + quad.ngeom == 15
    world = np.flatnonzero(model.geom_bodyid == 0)
    assert [model.geom(g).name for g in world] == ["ground"]
    assert model.nbody == 1 + quad.nbody  # the world, the quadrotor's bodies
    assert not any(n.startswith(("tile_", "nfz_")) for n in names)


# MuJoCo-v0 on map A, seed 0, gusts on: energy after each action and the final state, flown on
# the model that still held the 256 tiles and 19 no-fly volumes as geoms (they never collided, so
# moving them out of the model must change no bit). A deliberate change of the flight updates them.
REFERENCE_ACTIONS = (1, 1, 0, 3, 2, 2, 4)
REFERENCE_ENERGY_J = (462.01486445376196, 952.3209097349289, 1436.2058404537913,
                      1879.3440830196923, 2355.965346039427, 2819.4793909855925,
                      3116.098193746369)  # fmt: skip
REFERENCE_QPOS = (-9.948686936395237, -25.99504905883905, 0.17763390216535427,
                  0.9999985520172926, 0.001541949001185389, -1.2329520024440247e-06,
                  -0.0007199688015478496)  # fmt: skip
REFERENCE_TIME_S = 21.040000000000365


def test_a_flown_episode_is_bit_identical_to_the_tiled_model():
    from cpp_mujoco.physics.envs.single import MuJoCoEnv

    env = MuJoCoEnv(map="A", wind_speed=5.0, wind_direction=60.0, gust_std=1.5)
    env.reset(seed=0, options={"budget": 30})
    energy = []
    for action in REFERENCE_ACTIONS:
        *_, terminated, _, info = env.step(action)
        energy.append(info["energy_used_j"])
    assert terminated and info["landed"]
    assert tuple(energy) == REFERENCE_ENERGY_J
    assert tuple(env.data.qpos.tolist()) == REFERENCE_QPOS
    assert env.data.time == REFERENCE_TIME_S


def test_tiles_as_model_geoms_would_not_change_the_flight():
    """The same flight on the model plus the scenery as non-colliding geoms (what the arena was):
    identical to the last bit, whatever the flight code becomes."""
    grid_map = GridMap.from_ascii(["TTN", "TLT", "YTT"])
    config = PhysicsConfig(wind_speed=4.0, gust_std=1.0)
    scenery = Scenery(grid_map, config)
    arena = build_arena(grid_map, config)
    (tiles, tile_size, colours), (volumes, volume_size, volume_rgba) = (
        scenery.tiles(), scenery.volumes()
    )  # fmt: skip
    boxes = [(p, tile_size, c) for p, c in zip(tiles, colours, strict=True)]
    for pos, size, rgba in boxes + [(p, volume_size, volume_rgba) for p in volumes]:
        arena.worldbody.add(
            "geom", type="box", size=size, pos=pos, rgba=rgba, contype=0, conaffinity=0
        )
    tiled = compile_arena(arena)
    assert tiled.ngeom == 15 + 9 + 2
    runs = []
    for model in (compile_arena(build_arena(grid_map, config)), tiled):
        flight = Flight(model, grid_map, config)
        flight.reset(1, 1, rng=np.random.default_rng(5))
        results = [flight.move(5), flight.hover(5), flight.move(4), flight.land(4)]
        assert results[-1].landed
        runs.append([(r.energy, r.duration) for r in results] + [flight.data.qpos.tolist()])
    assert runs[0] == runs[1]


def test_realistic_airframe(params):
    assert 1.0 < params.mass < 2.5
    assert 2.0 <= params.thrust_to_weight <= 4.0
    assert 0.01 <= params.motor_tau <= 0.1


def test_allocation_full_rank_and_diagonal_rotors_spin_alike(params):
    A = params.allocation_matrix()
    assert np.linalg.matrix_rank(A) == 4
    xy = params.rotor_xy
    for i in range(4):
        opposite = int(np.argmin(np.linalg.norm(xy + xy[i], axis=1)))  # the diagonal partner
        assert np.allclose(xy[opposite], -xy[i])
        assert np.sign(params.yaw_coef[opposite]) == np.sign(params.yaw_coef[i])
    assert params.yaw_coef.sum() == pytest.approx(0.0)


def test_mujoco_applies_the_allocation_matrix(model, params):
    """Each rotor's generalized force in MuJoCo equals its allocation column (level attitude)."""
    data = mujoco.MjData(model)
    data.qpos[2] = 5.0
    A = params.allocation_matrix()
    for i in range(4):
        data.act[:] = 0.0
        data.act[i] = 1.0
        mujoco.mj_forward(model, data)
        f = data.qfrc_actuator
        assert np.allclose([f[2], f[3], f[4], f[5]], A[:, i], atol=1e-9)


def test_camera_fovy_gives_three_cells_at_altitude(model):
    cam = model.camera("quadrotor/downward").id
    assert model.cam_fovy[cam] == pytest.approx(camera_fovy(CONFIG, 3))
    half = math.radians(model.cam_fovy[cam]) / 2
    assert CONFIG.altitude * math.tan(half) == pytest.approx(1.5 * CONFIG.cell_size)


def test_level_footprint_is_the_three_by_three_block():
    geo = GridGeometry(8, 8, CONFIG.cell_size)
    x, y = geo.cell_center(3, 4)
    poly = footprint((x, y, CONFIG.altitude), np.eye(3).ravel(), corner_rays(camera_fovy(CONFIG)))
    cells = sorted(cells_in_footprint(poly, geo))
    assert cells == sorted(r * 8 + c for r in (2, 3, 4) for c in (3, 4, 5))


@pytest.mark.parametrize("theta_deg", [0.0, 10.0, 25.0])
def test_tilted_footprint_shifts_as_geometry_says(theta_deg):
    """A camera pitched by θ about the world y axis: the image edges along x land at
    h·tan(±α − θ) (α the half-angle) and the footprint is a trapezoid widening away from nadir."""
    h, fovy = 6.0, 90.0
    th = math.radians(theta_deg)
    rot = np.array([[math.cos(th), 0, math.sin(th)], [0, 1, 0], [-math.sin(th), 0, math.cos(th)]])
    poly = np.array(footprint((1.0, 2.0, h), rot.ravel(), corner_rays(fovy)))
    a = math.radians(fovy) / 2
    assert poly[:, 0].min() == pytest.approx(1.0 + h * math.tan(-a - th))
    assert poly[:, 0].max() == pytest.approx(1.0 + h * math.tan(a - th))
    for (cx, cy), sx in zip(poly, (-1, 1, 1, -1), strict=True):
        expect_y = h * math.tan(a) / (sx * math.tan(a) * math.sin(th) + math.cos(th))
        assert abs(cy - 2.0) == pytest.approx(expect_y)
        assert cx == pytest.approx(1.0 + h * math.tan(sx * a - th))
    assert inside_polygon(list(map(tuple, poly)), 1.0 - h * math.tan(th), 2.0)  # optical axis


def test_footprint_rejects_horizon_frames():
    rot = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=float)  # looking sideways
    assert footprint((0, 0, 6), rot.ravel(), corner_rays(90)) is None


def test_interval_energy_is_the_sum_over_physics_steps(model, params):
    """The closed-form per-step thrusts equal MuJoCo's actuator forces step by step."""
    power = PowerModel(params)
    k = 5
    energy = IntervalEnergy(power, model.opt.timestep, params.motor_tau, k)
    data = mujoco.MjData(model)
    data.qpos[2] = 5.0
    data.act[:] = [3.0, 4.0, 5.0, 6.0]
    ctrl = [6.0, 1.0, 3.0, 8.0]
    data.ctrl[:] = ctrl
    expected = energy(data.act.tolist(), ctrl)
    total = 0.0
    for _ in range(k):
        mujoco.mj_step(model, data)
        total += power.power(data.actuator_force.tolist()) * model.opt.timestep
    assert total == pytest.approx(expected, rel=1e-9)


def test_hover_power_is_momentum_theory(params):
    power = PowerModel(params)
    per_rotor = params.weight / 4
    disk = math.pi * params.rotor_radius**2
    ideal = 4 * per_rotor**1.5 / math.sqrt(2 * 1.225 * disk)
    assert power.power([per_rotor] * 4) == pytest.approx(
        ideal / params.power_efficiency + params.avionics_power
    )


def test_wind_direction_and_gust_statistics():
    north = Wind(PhysicsConfig(wind_speed=5.0, wind_direction=0.0), 0.02)
    assert north.steady == pytest.approx((0.0, -5.0, 0.0))  # from the north, blowing south
    fx, fy, _ = QuadraticDrag(1.225, 0.1).force((0.0, 2.0, 0.0), north.steady)  # flying into it
    assert fx == pytest.approx(0.0) and fy < 0.0
    gusty = Wind(PhysicsConfig(gust_std=2.0, gust_tau=1.0), 0.02)
    gusty.reset(np.random.default_rng(0))
    samples = np.array([gusty.velocity()[:2] for _ in range(50_000)])
    assert samples.std(axis=0) == pytest.approx([2.0, 2.0], rel=0.15)
    assert abs(samples.mean()) < 0.5


@pytest.mark.parametrize("size", [32, 23])  # 23x23 + 4 = 533 numbers: one just over a field
def test_a_large_map_builds_and_its_scenery_is_stored_whole(size):
    """MuJoCo takes at most 500 numbers in one custom field: the map is split over several, and
    the renderer's scenery reads back every cell."""
    from cpp_mujoco.map_generator import generate_from_seed

    grid_map = generate_from_seed(7, 32) if size == 32 else GridMap.from_ascii(
        ["L" + "T" * (size - 2) + "N"] + ["T" * size] * (size - 1), name="odd"
    )  # fmt: skip
    model = compile_arena(build_arena(grid_map, PhysicsConfig()))
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, 10)
    ours, stored = Scenery(grid_map, PhysicsConfig()), Scenery.from_model(model)
    assert (stored.geometry.height, stored.geometry.width) == grid_map.shape
    for a, b in zip(ours.tiles() + ours.volumes(), stored.tiles() + stored.volumes(), strict=True):
        assert np.array_equal(a, b)
