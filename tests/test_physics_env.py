"""``cpp_mujoco/MuJoCo-v0`` as a gymnasium env: spaces, options, info, checker, benchmark."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.bench.physics import benchmark_physics
from cpp_mujoco.maps import GridMap

SMALL = GridMap.from_ascii(["LTT", "TNT", "TTL"], name="small")
OPEN3 = GridMap.from_ascii(["TTT", "TLT", "TTT"], name="open")
INFO_KEYS = {
    "position", "budget", "landed", "crashed", "rejected", "coverage_ratio",
    "energy_used_j", "flight_time_s", "nfz_violations", "max_track_error_m", "tracking_error_m",
    "crash_reason", "guard_active", "guard_takeovers", "state_of_charge", "battery_voltage_v",
}  # fmt: skip


@pytest.fixture(scope="module")
def env():
    return gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL, wind_speed=2.0, gust_std=0.5)


def test_same_spaces_as_the_grid_env(env):
    grid = gym.make("cpp_mujoco/Grid-v0", map=SMALL)
    assert env.observation_space == grid.observation_space
    assert env.action_space == grid.action_space


def test_check_env_passes():
    check_env(gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL).unwrapped, skip_render_check=True)


def test_reset_options_and_info(env):
    obs, info = env.reset(seed=3, options={"start": (2, 2), "budget": 7})
    assert set(info) == INFO_KEYS
    assert info["position"] == (2, 2) and info["budget"] == 7
    assert obs["position"][2, 2] == 1 and obs["budget"][0] == 7
    assert info["crash_reason"] is None and info["energy_used_j"] == 0.0
    u = env.unwrapped
    assert u.model.nu == 4 and u.data.qpos[2] > 5.0  # airborne at cruise altitude
    obs, reward, terminated, truncated, info = env.step(1)  # east
    assert set(info) == INFO_KEYS and not truncated and not terminated
    assert info["position"] == (2, 2) and info["rejected"] and obs["safety"][0] == 1
    assert reward == pytest.approx(-0.2 - 1.0 + 0.4 * info["coverage_ratio"] * 6)
    assert info["flight_time_s"] == pytest.approx(u.config.move_duration, abs=0.05)


def test_same_seed_same_episode_as_the_grid_env():
    physics = gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL)
    grid = gym.make("cpp_mujoco/Grid-v0", map=SMALL)
    for seed in range(4):
        _, a = physics.reset(seed=seed)
        _, b = grid.reset(seed=seed)
        assert (a["position"], a["budget"]) == (b["position"], b["budget"])


def test_bad_start_and_budget_raise(env):
    with pytest.raises(ValueError, match="not a landing cell"):
        env.reset(options={"start": (0, 1)})
    with pytest.raises(ValueError):
        env.reset(options={"budget": 0})
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"speed": 3})


def test_unknown_keyword_is_a_type_error():
    with pytest.raises(TypeError, match="unknown option"):
        gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL, windspeed=3.0)


def test_step_after_the_end_needs_a_reset(env):
    env.reset(seed=0, options={"start": (0, 0), "budget": 5})
    *_, terminated, _, info = env.step(4)  # land where it started
    assert terminated and info["landed"] and not info["crashed"]
    with pytest.raises(RuntimeError):
        env.step(0)


def test_gusts_are_reproducible_from_the_seed():
    def fly(seed):
        e = gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL, gust_std=2.0)
        e.reset(seed=seed, options={"start": (0, 0), "budget": 9})
        for a in (2, 2, 1):
            *_, info = e.step(a)
        return info["energy_used_j"]

    assert fly(1) == fly(1)
    assert fly(1) != fly(2)


def test_benchmark_reports_rates():
    result = benchmark_physics(seconds=0.6)
    for key in ("env_steps_per_s", "raw_steps_per_s", "overhead_ratio", "real_time_factor"):
        assert np.isfinite(result[key]) and result[key] > 0
    assert result["overhead_ratio"] == pytest.approx(
        result["env_steps_per_s"] / result["raw_steps_per_s"]
    )


def test_landing_with_the_last_budget_unit_succeeds_as_on_the_grid():
    """Every grid action costs one unit; in calm air a landing must cost less than one."""
    grid_map = GridMap.from_ascii(["LT...", "L...."])
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=grid_map).unwrapped
    env.reset(options={"start": (0, 0), "budget": 3})
    for action in (1, 3, 4):  # east, back west, land with the last unit
        _, _, terminated, _, info = env.step(action)
    assert terminated and info["landed"] and not info["crashed"]
    assert info["energy_used_j"] < 3 * env.unit_energy


def test_data_holds_the_drone_after_every_step_and_at_every_frame_of_the_hook():
    """``env.data`` is the drone's ``MjData`` after each reset and step; while ``on_frame`` is
    set it is brought up to date at every camera frame (first and last of each action
    included) before the hook is called with the env."""
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=OPEN3, wind_speed=3.0).unwrapped
    env.reset(seed=0, options={"start": (1, 1), "budget": 6})
    flight, q = env.flight, env.flight.cols[0].start
    times, heights = [], []
    env.on_frame = lambda e: (times.append(float(e.data.time)), heights.append(e.data.qpos[2]))
    _, _, _, _, info = env.step(1)
    np.testing.assert_array_equal(env.data.qpos[:3], flight.state[0, q : q + 3])
    assert env.data.time == flight.state[0, 0] == info["flight_time_s"]
    rate = env.config.camera_rate
    assert times[0] == 0.0 and times[-1] == env.data.time  # the action's first and last frames
    gaps = np.diff(times)
    assert np.all(gaps >= 0) and gaps[1:-1].max() <= 1 / rate + 2.5 * env.config.control_dt
    assert np.ptp(heights) < 0.5  # a level move at cruise altitude, frame by frame
    env.on_frame = None
    env.step(2)
    assert len(times) == len(heights) and times[-1] < env.data.time  # the hook is off
