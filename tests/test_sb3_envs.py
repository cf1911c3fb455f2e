"""Stable-Baselines3 runs on both envs: DQN trains on Grid-v0, make_vec_env builds MuJoCo-v0."""

import gymnasium as gym
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.maps import GridMap

pytest.importorskip("stable_baselines3")
from stable_baselines3 import DQN  # noqa: E402
from stable_baselines3.common.env_checker import check_env  # noqa: E402
from stable_baselines3.common.env_util import make_vec_env  # noqa: E402

TINY = GridMap.from_ascii(["LTT", "TNT", "TTL"], name="tiny")
SHORT = dict(map=TINY, min_budget=3, max_budget=6)


def test_sb3_env_checker_passes_on_both_envs(recwarn):
    check_env(gym.make("cpp_mujoco/Grid-v0", **SHORT).unwrapped)
    check_env(gym.make("cpp_mujoco/MuJoCo-v0", **SHORT).unwrapped)
    assert not [w for w in recwarn if "stable_baselines3" in str(w.filename)]


def test_dqn_multi_input_policy_trains_on_the_grid_env(one_thread):
    env = gym.make("cpp_mujoco/Grid-v0", **SHORT)
    model = DQN(
        "MultiInputPolicy", env, policy_kwargs={"net_arch": [16]}, learning_starts=50,
        buffer_size=1_000, batch_size=16, train_freq=4, seed=0, device="cpu",
    )  # fmt: skip
    model.learn(total_timesteps=300)
    assert model.num_timesteps == 300 and len(model.ep_info_buffer) >= 30  # ≤ 6 steps each
    obs, _ = env.reset(seed=1)
    action, _ = model.predict(obs, deterministic=True)  # a 0-d int array
    _, reward, *_ = env.step(action)
    assert np.isfinite(reward)


@pytest.mark.parametrize("n_envs", [1, 2])
def test_make_vec_env_builds_and_steps_the_physics_env(n_envs):
    # make_vec_env asks for render_mode="rgb_array" first: the env must accept it
    vec = make_vec_env("cpp_mujoco/MuJoCo-v0", n_envs=n_envs, seed=0, env_kwargs=SHORT)
    assert vec.get_attr("render_mode") == ["rgb_array"] * n_envs
    obs = vec.reset()
    assert obs["coverage"].shape == (n_envs, 3, 3)
    for _ in range(2):
        obs, reward, done, infos = vec.step(np.full(n_envs, 1))  # east
    assert reward.shape == (n_envs,) and all(i["energy_used_j"] > 0 for i in infos)
    vec.close()
