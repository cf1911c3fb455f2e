"""Stable-Baselines3 as a client of our policies and a source of them: SB3's evaluate_policy runs
a bundled agent (GreedyAgent.predict), and an SB3 DQN runs through our evaluate (SB3Policy)."""

import pickle

import gymnasium as gym
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.agent import load_agent
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.protocol.policy import SB3Policy, as_policy

pytest.importorskip("stable_baselines3")
from stable_baselines3 import DQN  # noqa: E402
from stable_baselines3.common.evaluation import evaluate_policy  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv  # noqa: E402

TINY = GridMap.from_ascii(["LTT", "TNT", "TTL"], name="tiny")


@pytest.fixture(scope="module")
def dqn():
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    env = gym.make("cpp_mujoco/Grid-v0", map=TINY, min_budget=3, max_budget=6)
    model = DQN(
        "MultiInputPolicy", env, policy_kwargs={"net_arch": [16]}, learning_starts=50,
        buffer_size=1_000, batch_size=16, train_freq=4, seed=0, device="cpu",
    )  # fmt: skip
    model.learn(total_timesteps=200)
    torch.set_num_threads(before)
    return model


def play(env, choose, episodes: int, seed: int):
    """(returns, lengths) of ``episodes`` episodes of ``env`` from ``seed``, one obs at a time."""
    returns, lengths = [], []
    obs, _ = env.reset(seed=seed)
    for _ in range(episodes):
        total, steps, done = 0.0, 0, False
        while not done:
            obs, reward, done, _, _ = env.step(choose(obs))
            total, steps = total + reward, steps + 1
        returns.append(total)
        lengths.append(steps)
        obs, _ = env.reset()
    return returns, lengths


# ----------------------------------------------------------------------------- our agent in SB3
@pytest.mark.parametrize(
    ("env_id", "episodes", "options"),
    [("cpp_mujoco/Grid-v0", 5, {}), ("cpp_mujoco/MuJoCo-v0", 2, {"max_budget": 27})],
)
def test_sb3_evaluate_policy_runs_a_bundled_agent(one_thread, env_id, episodes, options):
    agent = load_agent("A")
    vec = DummyVecEnv([lambda: gym.make(env_id, map="A", **options)])
    vec.seed(0)
    returns, lengths = evaluate_policy(
        agent, vec, n_eval_episodes=episodes, return_episode_rewards=True, warn=False
    )
    expected = play(gym.make(env_id, map="A", **options), agent.act, episodes, seed=0)
    np.testing.assert_allclose(returns, expected[0], rtol=1e-5)
    assert lengths == expected[1]
    assert all(r > 0 for r in returns)  # the agent covers and lands: no crash penalty


def test_greedy_agent_predict_follows_sb3s_contract(one_thread):
    agent = load_agent("C")
    mdp = GridMDP(load_map("C"), 3)
    mdp.reset(np.random.default_rng(0))
    obs = mdp.observation()
    actions, state = agent.predict(obs, state=None, episode_start=np.ones(3, bool))
    assert state is None and isinstance(actions, np.ndarray)
    np.testing.assert_array_equal(actions, agent.act(obs))
    single, _ = agent.predict(mdp.observation_of(1))
    assert int(single) == actions[1]
    with pytest.raises(ValueError, match="deterministic=False"):
        agent.predict(obs, deterministic=False)
    agent.reset(3, seed=0)  # the episode start is part of the protocol, and a no-op here
    np.testing.assert_array_equal(agent.act(obs), actions)


# ----------------------------------------------------------------------------- SB3 models in ours
def test_sb3_dqn_through_our_grid_protocol_matches_its_own_predict(dqn):
    result = evaluate(dqn, TINY, budgets=range(3, 7))  # adapted by as_policy
    assert result.policy_name == "sb3-dqn" and result.landed.size == 8
    env = gym.make("cpp_mujoco/Grid-v0", map=TINY)
    for i, (start, budget) in enumerate(zip(result.starts, result.budgets, strict=True)):
        obs, info = env.reset(options={"start": tuple(start), "budget": int(budget)})
        steps, done = 0, False
        while not done:
            obs, _, done, _, info = env.step(dqn.predict(obs, deterministic=True)[0])
            steps += 1
        assert (steps, info["landed"]) == (result.steps[i], result.landed[i])
        assert info["coverage_ratio"] == pytest.approx(result.coverage[i])


def test_sb3_dqn_through_our_physics_protocol(dqn):
    result = evaluate(dqn, TINY, backend="mujoco", budgets=[4], workers=1)
    assert result.landed.size == 2 and "energy_used_j" in result.physics
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=TINY).unwrapped
    for i, start in enumerate(result.starts):
        obs, info = env.reset(seed=i, options={"start": tuple(start), "budget": 4})
        done = False
        while not done:
            obs, _, done, _, info = env.step(int(dqn.predict(obs, deterministic=True)[0]))
        assert info["coverage_ratio"] == pytest.approx(result.coverage[i])
        assert info["landed"] == result.landed[i]


def test_sb3_policy_pickles_to_its_network_only(dqn):
    policy = SB3Policy(dqn)
    copy = pickle.loads(pickle.dumps(policy))
    assert not isinstance(copy.model, DQN)  # the policy network: no replay buffer, no env
    mdp = GridMDP(TINY, 6)
    mdp.reset(np.random.default_rng(1))
    obs = mdp.observation()
    np.testing.assert_array_equal(copy.act(obs), policy.act(obs))
    assert as_policy(policy) is policy


def test_sb3_policy_carries_recurrent_state_and_episode_starts():
    seen = []

    class Recurrent:
        def predict(self, obs, state=None, episode_start=None, deterministic=False):
            seen.append((state, episode_start.copy(), deterministic))
            n = obs["coverage"].shape[0]
            assert obs["map"].shape == (n, 3, 3, 3) and obs["map"].flags.writeable
            return np.full(n, 4), ("h", len(seen))

    policy = SB3Policy(Recurrent())
    mdp = GridMDP(TINY, 2)
    mdp.reset(np.random.default_rng(0))
    policy.reset(2)
    policy.act(mdp.observation())
    policy.act(mdp.observation())
    policy.reset(2, seed=1)
    policy.act(mdp.observation())
    assert [s for s, _, _ in seen] == [None, ("h", 1), None]
    assert [e.tolist() for _, e, _ in seen] == [[True, True], [False, False], [True, True]]
    assert all(d for _, _, d in seen)
    with pytest.raises(TypeError, match="not a policy"):
        as_policy(object())
