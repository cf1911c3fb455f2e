"""The quadrotor model, the arena, and the flight's camera footprint, drag, wind and energy
against hand computations."""

import math

import mujoco
import numpy as np
import pytest

from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.physics import action as kind  # the flight's macro-action kinds
from cpp_mujoco.physics.air.wind import Wind

# dm_control's mjcf as the arena imports it (without dm_control's headless GLFW warning)
from cpp_mujoco.physics.arena import build_arena, camera_fovy, compile_arena, mjcf
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.flight import Flight
from cpp_mujoco.physics.power.rotor import PowerModel
from cpp_mujoco.physics.quadrotor import QuadrotorParams, quadrotor_xml
from cpp_mujoco.physics.view.scenery import Scenery

CONFIG = PhysicsConfig()
EIGHT = GridMap.from_ascii(["TTTTTTTT"] * 3 + ["TTTTLTTT"] + ["TTTTTTTT"] * 4, name="eight")


def posed(row: int, col: int, rot: np.ndarray, config: PhysicsConfig = CONFIG) -> Flight:
    """One drone over ``row``, ``col`` of :data:`EIGHT` at cruise altitude, its body turned by
    ``rot`` (body → world), MuJoCo's forward pass run: its camera pose is the flight's own."""
    flight = Flight.alone(EIGHT, config)
    flight.reset(0, row, col, math.inf, np.random.default_rng(0))
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rot, dtype=float).ravel())
    q = flight.cols[0].start
    flight.state[0, q + 3 : q + 7] = quat
    flight.sims.forward([0])
    return flight


def record_ticks(flight: Flight, whole: bool = False) -> list:
    """Per physics call of the flight (one per control tick), drone 0 as the tick left it:
    its state row, the wind it flew in, the load energy its pack had carried, and with
    ``whole`` a copy of its whole ``MjData`` (else None)."""
    ticks, step = [], flight._step

    def recording(drones, nstep):
        copy = flight.copy_data(0, mujoco.MjData(flight.model)) if whole else None
        state, wind = flight.state[0].copy(), flight.wind_now[0].copy()
        ticks.append((state, wind, float(flight.battery.load_j[0]), copy))
        step(drones, nstep)

    flight._step = recording
    return ticks


def corners_sorted(points) -> np.ndarray:
    """Polygon corners in a fixed order (by x to the micrometre, then y) to compare as sets."""
    return np.array(sorted(map(tuple, points), key=lambda p: (round(p[0], 6), p[1])))


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
    """Tiles and no-fly volumes are render-time scenery (physics/view/scenery.py), not model geoms:
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
    """The same flight on the model plus the scenery as non-colliding geoms:
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
        flight = Flight(model, grid_map, config, 1, np.zeros((1, grid_map.target.size), bool))
        flight.reset(0, 1, 1, math.inf, np.random.default_rng(5))
        results = [flight.fly_one(kind.MOVE, 5), flight.fly_one(kind.HOVER, 5),
                   flight.fly_one(kind.MOVE, 4), flight.fly_one(kind.LAND, 4)]  # fmt: skip
        assert results[-1].landed
        runs.append([(r.energy, r.duration) for r in results] + [flight.state[0].tolist()])
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
    flight = posed(3, 4, np.eye(3))
    x, y = flight.geo.cell_center(3, 4)
    half = 1.5 * CONFIG.cell_size
    poly = corners_sorted(flight.footprint(0))
    expect = [(x + sx * half, y + sy * half) for sx in (-1, 1) for sy in (-1, 1)]
    assert poly == pytest.approx(corners_sorted(expect))
    assert flight.camera.capture(np.array([0])).tolist() == [8]  # the landing cell is no target
    cells = np.flatnonzero(flight.coverage[0]).tolist()
    assert cells == sorted(r * 8 + c for r in (2, 3, 4) for c in (3, 4, 5))


@pytest.mark.parametrize("theta_deg", [0.0, 10.0, 25.0])
def test_tilted_footprint_shifts_as_geometry_says(theta_deg):
    """The drone pitched by θ about the world y axis: seen from its camera at (x, y, h), the
    image edges along x land at x + h·tan(±α − θ) (α the half-angle), the footprint is a
    trapezoid widening away from nadir, and a frame sees the cells whose centres lie in it and
    within the nominal footprint's half width of the camera — the optical axis' among them."""
    th = math.radians(theta_deg)
    rot = np.array([[math.cos(th), 0, math.sin(th)], [0, 1, 0], [-math.sin(th), 0, math.cos(th)]])
    flight = posed(3, 4, rot)
    px, py, h = flight.camera.cam_xpos[0]
    a = math.radians(flight.model.cam_fovy[flight.camera.cam_id]) / 2
    poly = np.array(flight.footprint(0))
    x_lo, x_hi = px + h * math.tan(-a - th), px + h * math.tan(a - th)
    assert poly[:, 0].min() == pytest.approx(x_lo)
    assert poly[:, 0].max() == pytest.approx(x_hi)
    # the half width across y of the edge at x_lo (sx = −1) and at x_hi (sx = 1)
    t, s, c = math.tan(a), math.sin(th), math.cos(th)
    wide = {sx: h * t / (sx * t * s + c) for sx in (-1, 1)}
    signs = [(sx, sy) for sx in (-1, 1) for sy in (-1, 1)]
    expect = [(px + h * math.tan(sx * a - th), py + sy * wide[sx]) for sx, sy in signs]
    assert corners_sorted(poly) == pytest.approx(corners_sorted(expect))
    x, y = poly[:, 0], poly[:, 1]
    assert (x * np.roll(y, -1) - np.roll(x, -1) * y).sum() > 0  # counter-clockwise
    # the cells seen: centres in the trapezoid (its half width grows linearly from x_lo to
    # x_hi) and within the nominal half width of the camera
    flight.camera.capture(np.array([0]))
    nominal = CONFIG.altitude * math.tan(a)
    expect_cells = []
    for cell, (cx, cy) in enumerate(flight.geo.centers()):
        u = (cx - x_lo) / (x_hi - x_lo)
        in_trapezoid = 0 <= u <= 1 and abs(cy - py) <= wide[-1] + u * (wide[1] - wide[-1])
        if in_trapezoid and abs(cx - px) <= nominal and abs(cy - py) <= nominal:
            expect_cells.append(cell)
    seen = np.flatnonzero(flight.coverage[0]).tolist()
    assert seen == expect_cells
    row, col = flight.geo.cell_of(px - h * math.tan(th), py)  # where the optical axis lands
    assert row * 8 + col in seen


def test_footprint_rejects_horizon_frames():
    rot = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=float)  # looking sideways
    flight = posed(3, 4, rot)
    assert flight.footprint(0) is None
    assert flight.camera.capture(np.array([0])).tolist() == [0]
    assert not flight.coverage[0].any()


def test_interval_energy_is_the_sum_over_physics_steps():
    """The energy the flight books per control tick (closed-form per-step thrusts from the
    rotor states and commands) equals the thrust power of MuJoCo's actuator forces summed over
    the tick's physics steps, from rotors far from their commands to a hover and a move."""
    config = PhysicsConfig(power_model="momentum")  # the per-step integral, airspeed-blind
    flight = Flight.alone(EIGHT, config)
    flight.reset(0, 3, 4, math.inf, np.random.default_rng(0))
    flight.state[0, flight.cols[2]] = [3.0, 4.0, 5.0, 6.0]  # the rotors' thrusts
    ticks = record_ticks(flight, whole=True)
    assert flight.fly_one(kind.HOVER, 3 * 8 + 4).failure is None
    assert flight.fly_one(kind.MOVE, 3 * 8 + 5).arrived
    power, dt, k = flight.energy_of.power, flight.model.opt.timestep, flight.k
    assert k == 5 and len(ticks) > 200
    booked = 0.0
    for state, _, load_j, data in ticks:
        energy, booked = load_j - booked, load_j
        assert not np.array_equal(state[flight.ctrl_cols], state[flight.cols[2]])  # in transit
        total = 0.0
        for _ in range(k):
            mujoco.mj_step(flight.model, data)
            total += power.power(data.actuator_force.tolist()) * dt
        assert total == pytest.approx(energy, rel=1e-9)


def test_hover_power_is_momentum_theory(params):
    power = PowerModel(params)
    per_rotor = params.weight / 4
    disk = math.pi * params.rotor_radius**2
    ideal = 4 * per_rotor**1.5 / math.sqrt(2 * 1.225 * disk)
    assert power.power([per_rotor] * 4) == pytest.approx(
        ideal / params.power_efficiency + params.avionics_power
    )


def test_wind_direction_drag_and_gust_statistics():
    flight = Flight.alone(EIGHT, PhysicsConfig(wind_speed=5.0, wind_direction=0.0))
    flight.reset(0, 3, 4, math.inf, np.random.default_rng(0))
    assert flight.weather.steady[0] == pytest.approx((0.0, -5.0, 0.0))  # from the north
    v = flight.cols[1].start
    flight.state[0, v : v + 3] = (0.0, 2.0, 0.0)  # flying into it
    ticks = record_ticks(flight)
    flight.fly_one(kind.HOVER, 3 * 8 + 4)
    state, wind, *_ = ticks[0]
    assert wind == pytest.approx((0.0, -5.0, 0.0))
    fx, fy, fz = state[flight.force_cols]
    assert fx == pytest.approx(0.0) and fz == pytest.approx(0.0) and fy < 0.0
    assert fy == pytest.approx(-flight.half_rho_cda * 7.0**2)  # ½ρC_dA·|v_rel|·v_rel
    for state, wind, *_ in ticks:  # the drag of every tick, from the air the drone flew in
        rel = wind - state[flight.cols[1]][:3]
        drag = flight.half_rho_cda * np.linalg.norm(rel) * rel
        assert state[flight.force_cols] == pytest.approx(drag, rel=1e-12, abs=1e-15)
    gusty = Wind(PhysicsConfig(gust_std=2.0, gust_tau=1.0), 0.02)
    gusty.reset(0, np.random.default_rng(0))
    drone, where = np.zeros(1, dtype=np.int64), np.zeros((1, 3))
    samples = np.array(
        [gusty.velocity(drone, np.array([0.02 * t]), where)[0, :2] for t in range(50_000)]
    )
    assert samples.std(axis=0) == pytest.approx([2.0, 2.0], rel=0.15)
    assert abs(samples.mean()) < 0.5


@pytest.mark.parametrize("size", [32, 23])  # 23x23 + 4 = 533 numbers: one just over a field
def test_a_large_map_builds_and_its_scenery_is_stored_whole(size):
    """MuJoCo takes at most 500 numbers in one custom field: the map is split over several, and
    the renderer's scenery reads back every cell."""
    from cpp_mujoco.map_sets.generator import generate_from_seed

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
