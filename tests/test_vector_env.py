"""The native batched env: gymnasium's vector API; step-by-step agreement with the single env."""

import gymnasium as gym
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401
from cpp_mujoco.grid.vector_env import GridVectorEnv

INFO_KEYS = ("position", "budget", "landed", "crashed", "rejected", "coverage_ratio")


def test_make_vec_returns_the_native_array_env():
    envs = gym.make_vec("cpp_mujoco/Grid-v0", num_envs=8, map="B")
    assert isinstance(envs.unwrapped, GridVectorEnv)
    obs, info = envs.reset(seed=0)
    assert obs["coverage"].shape == (8, 16, 16) and obs["map"].shape == (8, 3, 16, 16)
    assert envs.observation_space.contains(obs)
    assert info["_budget"].all()


@pytest.mark.parametrize("map_name", ["A", "B", "C"])
def test_single_and_batched_envs_agree_step_by_step(map_name):
    n, steps = 16, 400
    envs = gym.make_vec("cpp_mujoco/Grid-v0", num_envs=n, map=map_name)
    singles = [gym.make("cpp_mujoco/Grid-v0", map=map_name) for _ in range(n)]
    rng = np.random.default_rng(1)
    vobs, vinfo = envs.reset(seed=3)

    def restart(i):
        start, budget = tuple(int(v) for v in vinfo["position"][i]), int(vinfo["budget"][i])
        return singles[i].reset(options={"start": start, "budget": budget})

    sobs = [restart(i)[0] for i in range(n)]
    pending = np.zeros(n, dtype=bool)
    episodes = 0
    for _ in range(steps):
        # bias towards landing so episodes end both ways (landed and crashed)
        actions = rng.choice(5, size=n, p=[0.22, 0.22, 0.22, 0.22, 0.12])
        vobs, vrew, vterm, vtrunc, vinfo = envs.step(actions)
        assert not vtrunc.any()
        for i in range(n):
            if pending[i]:  # NEXT_STEP autoreset: this step restarted env i
                assert vrew[i] == 0 and not vterm[i]
                sobs[i], info = restart(i)
                episodes += 1
            else:
                sobs[i], reward, term, trunc, info = singles[i].step(int(actions[i]))
                assert reward == pytest.approx(vrew[i]) and term == vterm[i] and not trunc
            for key in INFO_KEYS:
                np.testing.assert_allclose(np.asarray(info[key]), vinfo[key][i], err_msg=key)
            for key, value in sobs[i].items():
                np.testing.assert_array_equal(value, vobs[key][i], err_msg=key)
        pending = vterm.copy()
    assert episodes > 30


def test_same_step_autoreset_reports_the_final_observation():
    envs = GridVectorEnv(num_envs=4, map="A", autoreset_mode="SameStep")
    envs.reset(seed=0, options={"budget": 1})
    obs, reward, terminated, _, info = envs.step(np.full(4, 4))  # everyone lands at once
    assert terminated.all() and info["_final_obs"].all()
    assert info["final_info"]["landed"].all()
    assert info["final_obs"]["coverage"].reshape(4, -1).sum(1).min() > 0
    assert obs["coverage"].sum() == 0  # already restarted


def test_disabled_autoreset_with_reset_mask():
    envs = GridVectorEnv(num_envs=3, map="A", autoreset_mode="Disabled")
    envs.reset(seed=0, options={"budget": 1})
    envs.step(np.array([4, 4, 4]))
    obs, info = envs.reset(options={"reset_mask": np.array([True, False, False])})
    assert not info["landed"][0] and info["landed"][1:].all()


def test_reset_options_per_env():
    envs = GridVectorEnv(num_envs=2, map="C")
    starts = np.argwhere(envs.grid_map.landing)[:2]
    _, info = envs.reset(options={"start": starts, "budget": np.array([30, 40])})
    np.testing.assert_array_equal(info["position"], starts)
    np.testing.assert_array_equal(info["budget"], [30, 40])
