"""Flying grid actions: hover, step response, scripted missions, camera coverage, energy."""

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.grid.actions import EAST, LAND, NORTH, SOUTH, WEST
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics import action as kind  # the flight's macro-action kinds
from cpp_mujoco.physics.arena import GridGeometry
from cpp_mujoco.physics.calibration import calibration, unit_energy
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.envs.single import MuJoCoEnv
from cpp_mujoco.physics.flight import EMERGENCY_LANDING, Flight

CONFIG = PhysicsConfig()
OPEN = GridMap.from_ascii(["TTTTT", "TTTTT", "TTLTT", "TTTTT", "TTTTT"], name="open")
STRIP = GridMap.from_ascii(["TTTTTT", "LLTTTT", "TTTTTT"], name="strip")


def make_flight(row=2, col=2, capacity=math.inf, grid_map=OPEN, config=CONFIG) -> Flight:
    """One drone in an arena of its own, hovering over (row, col) with ``capacity`` J."""
    flight = Flight.alone(grid_map, config)
    flight.reset(0, row, col, capacity, np.random.default_rng(0))
    return flight


def test_hover_thrust_equals_weight():
    f = make_flight()
    result = f.fly_one(kind.HOVER, 12)
    assert result.failure is None
    total = f.copy_data(0, mujoco.MjData(f.model)).actuator_force.sum()
    assert total == pytest.approx(f.params.weight, rel=1e-3)
    assert np.linalg.norm(f.position(0) - f.waypoint(12)) < 0.02


def test_one_cell_step_response():
    f = make_flight()
    f.trace = []
    result = f.fly_one(kind.MOVE, 13)  # east
    assert result.arrived and result.failure is None
    assert result.duration <= CONFIG.move_duration + 1.0
    assert result.tracking_error < CONFIG.arrive_pos_tol
    trace = np.array(f.trace)
    goal_x = f.waypoint(13)[0]
    overshoot = trace[:, 1].max() - goal_x
    assert overshoot < 0.05 * CONFIG.cell_size
    assert np.abs(trace[:, 2] - f.waypoint(13)[1]).max() < 0.05  # no cross-track wobble
    assert np.abs(trace[:, 3] - f.cruise_z).max() < 0.1  # holds altitude


def test_scripted_out_and_back_visits_exactly_the_commanded_cells_and_lands():
    env = MuJoCoEnv(map=STRIP)
    env.reset(seed=0, options={"start": (1, 1), "budget": 20})
    env.unwrapped.flight.trace = trace = []
    actions = [EAST, EAST, NORTH, SOUTH, WEST, WEST, LAND]
    cells = [(1, 2), (1, 3), (0, 3), (1, 3), (1, 2), (1, 1), (1, 1)]
    for a, cell in zip(actions, cells, strict=True):
        _, _, terminated, _, info = env.step(a)
        assert info["position"] == cell and not info["rejected"]
    assert terminated and info["landed"] and not info["crashed"]
    geo = GridGeometry(3, 6, CONFIG.cell_size)
    visited = {geo.cell_of(x, y) for _, x, y, _ in trace}
    assert visited == {(1, 1), (1, 2), (1, 3), (0, 3)}
    # touchdown is a contact between the landing gear and the ground
    data, model = env.data, env.model
    ground = model.geom("ground").id
    pairs = {(int(data.contact.geom1[i]), int(data.contact.geom2[i])) for i in range(data.ncon)}
    touching = {model.geom(a if b == ground else b).name for a, b in pairs if ground in (a, b)}
    assert touching and touching <= {"quadrotor/skid_l", "quadrotor/skid_r"}
    assert data.qpos[2] < 0.3


def test_camera_coverage_contains_grid_coverage():
    rng = np.random.default_rng(3)
    env = MuJoCoEnv(map="B")
    grid = GridMDP(env.grid_map, 1)
    start = tuple(int(v) for v in np.argwhere(env.grid_map.landing)[0])
    env.reset(seed=0, options={"start": start, "budget": 40})
    grid.reset(rng, start=start, budget=40)
    for _ in range(14):
        action = int(rng.integers(4))
        obs, _, terminated, _, info = env.step(action)
        grid.step(np.array([action]))
        assert info["position"] == tuple(int(v) for v in divmod(grid.position[0], grid.width))
        physics_cov = obs["coverage"].astype(bool).ravel()
        assert not (grid.coverage[0] & ~physics_cov).any()
        assert not terminated
    assert info["nfz_violations"] == 0


def test_one_budget_unit_per_nominal_move_and_more_upwind():
    cal = calibration(CONFIG)
    unit = unit_energy(CONFIG)
    assert cal["move_energy_max_j"] / cal["move_energy_min_j"] < 1.01
    assert 0.8 < cal["hover_energy_j"] / unit < 1.0  # hovering a move's duration costs a bit less

    def fly(actions, **wind):
        env = MuJoCoEnv(map=OPEN, **wind)
        env.reset(seed=0, options={"start": (2, 2), "budget": 10})
        for a in actions:
            *_, info = env.step(a)
        return info

    calm = fly((NORTH, NORTH, SOUTH, SOUTH))
    moves = calm["energy_used_j"] / cal["unit_energy_j"]  # in calibrated moves
    assert moves == pytest.approx(4.0, abs=0.05)
    assert unit == pytest.approx(cal["unit_energy_j"] * (1 + CONFIG.unit_margin))
    assert calm["budget"] == 10 - 4  # the shown budget keeps pace with the grid's count
    # a 12 m/s wind from the north: the headwind leg costs far more than the tailwind leg and
    # than calm air (at moderate airspeed translational lift makes flight cheaper than hover:
    # tests/test_power_model.py)
    headwind = fly((NORTH,), wind_speed=12.0, wind_direction=0.0)["energy_used_j"]
    tailwind = fly((SOUTH,), wind_speed=12.0, wind_direction=0.0)["energy_used_j"]
    assert headwind > 1.2 * tailwind
    assert headwind > 1.2 * fly((NORTH,))["energy_used_j"]


def test_calibration_cache_round_trip(tmp_path, monkeypatch):
    from cpp_mujoco.physics import calibration as cal_module

    monkeypatch.setenv("CPP_MUJOCO_CACHE", str(tmp_path))
    monkeypatch.setattr(cal_module, "_MEMO", {})
    config = PhysicsConfig(move_duration=2.5)
    first = cal_module.unit_energy(config)
    files = list((tmp_path / "calibration").glob("*.json"))
    assert len(files) == 1
    monkeypatch.setattr(cal_module, "calibrate", lambda c: pytest.fail("should read the cache"))
    monkeypatch.setattr(cal_module, "_MEMO", {})
    assert cal_module.unit_energy(config) == first
    # weather does not change the unit
    assert cal_module.unit_energy(PhysicsConfig(move_duration=2.5, wind_speed=5.0)) == first


def test_random_actions_never_enter_no_fly_airspace():
    grid_map = GridMap.from_ascii(["TNT.", "LTNT", "TTYT", "LN.T"], name="maze")
    env = MuJoCoEnv(map=grid_map)
    rng = np.random.default_rng(7)
    for episode in range(3):
        env.reset(seed=episode, options={"budget": 12})
        terminated, rejected = False, 0
        while not terminated:
            _, _, terminated, _, info = env.step(int(rng.integers(4)))
            rejected += info["rejected"]
            assert info["nfz_violations"] == 0
            assert not grid_map.nfz[info["position"]]
        assert rejected > 0  # the safety controller was exercised


def test_budget_spent_mid_move_lands_where_the_uav_is_and_ends_in_a_crash():
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=OPEN, wind_speed=12.0, wind_direction=0.0)
    env.reset(seed=0, options={"start": (2, 2), "budget": 1})
    flight = env.unwrapped.flight
    flight.trace = []
    obs, reward, terminated, truncated, info = env.step(NORTH)  # 12 m/s headwind: > 1 unit
    assert terminated and not truncated
    assert info["crashed"] and not info["landed"]
    assert info["crash_reason"] == EMERGENCY_LANDING
    assert info["budget"] == 0
    newly_seen = int((obs["coverage"].astype(bool) & OPEN.target).sum())
    assert reward == pytest.approx(0.4 * newly_seen - 0.2 - 150.0)
    # the failsafe landed it upright on its skids, on the reserve, between the two cells
    assert flight._ground_contact(0) is True
    assert info["energy_used_j"] > flight.capacity[0]
    trace = np.array(flight.trace)
    along, across = np.abs(trace[-1, 1:3] - trace[0, 1:3])[::-1]  # north, east
    assert 0.3 < along < flight.config.cell_size - 0.3  # down between the cells, not at either
    assert across < 0.2


def test_budget_reaching_zero_unlanded_is_a_crash():
    env = MuJoCoEnv(map=OPEN)
    env.reset(seed=0, options={"start": (2, 2), "budget": 1})
    obs, reward, terminated, _, info = env.step(NORTH)  # about one unit: floor → 0, or cut
    assert terminated and info["crashed"] and info["budget"] == 0
    newly_seen = int((obs["coverage"].astype(bool) & OPEN.target).sum())
    assert reward == pytest.approx(0.4 * newly_seen - 0.2 - 150.0)


def test_physical_failure_is_a_crash_not_an_exception():
    env = MuJoCoEnv(map=OPEN)
    env.reset(seed=0, options={"start": (2, 2), "budget": 5})
    q = env.flight.cols[0].start  # the drone's state row; ``env.data`` is a copy of it
    env.flight.state[0, q + 3 : q + 7] = (0.0, 1.0, 0.0, 0.0)  # upside down
    _, reward, terminated, _, info = env.step(EAST)
    assert terminated and info["crashed"] and info["crash_reason"] == "flipped over"
    assert math.isfinite(reward)


def test_shown_budget_keeps_pace_with_the_grid_over_a_long_mission():
    """30 moves then a landing on the last unit: lands in physics as it would on the grid."""
    env = MuJoCoEnv(map=OPEN)
    env.reset(seed=0, options={"start": (2, 2), "budget": 31})
    for k in range(30):
        *_, info = env.step(NORTH if k % 2 == 0 else SOUTH)
        assert info["budget"] == 31 - (k + 1), f"after {k + 1} moves"
    *_, terminated, _, info = env.step(4)
    assert terminated and info["landed"] and not info["crashed"]


def test_a_landing_begun_with_budget_left_finishes_on_the_reserve():
    """On the grid a landing with one unit left always succeeds; in physics a landing that
    outlasts the budget's energy (gusts, a strong wind) touches down on the reserve, where the
    failsafe would have landed it anyway — landed, not a crash."""
    flight = make_flight(capacity=5000.0)
    flight.energy_used[0] = 4900.0  # 100 J left of the budget: a fifth of what a landing draws
    result = flight.fly_one(kind.LAND, 2 * 5 + 2)
    assert result.landed and result.failure is None
    assert flight.energy_used[0] > flight.capacity[0] + 250.0
    # a move with the same energy left is cut short by the failsafe instead
    flight.reset(0, 2, 2, 5000.0, np.random.default_rng(0))
    flight.energy_used[0] = 4900.0
    result = flight.fly_one(kind.MOVE, 1 * 5 + 2)
    assert not result.landed and result.failure == EMERGENCY_LANDING
