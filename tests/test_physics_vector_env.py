"""The batched physics env flies exactly what N single ``MuJoCo-v0`` envs fly."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.grid.wind import GridWind
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.envs.vector import MuJoCoVectorEnv

# an open 5×6 map: landing strip in the middle row, targets around, one no-fly cell
MAP = GridMap.from_ascii(["TTTTTT", "T..N.T", "TLLLLT", "T....T", "TTTTTT"], name="open")
KEYS = (
    "budget", "landed", "crashed", "rejected", "coverage_ratio", "energy_used_j",
    "flight_time_s", "nfz_violations", "max_track_error_m", "tracking_error_m",
    "state_of_charge", "battery_voltage_v", "crash_reason", "guard_active", "guard_takeovers",
)  # fmt: skip


def _same(single: dict, batched: dict, i: int, where: str) -> None:
    assert tuple(single["position"]) == tuple(batched["position"][i]), where
    for key in KEYS:
        a, b = single[key], batched[key][i]
        if isinstance(a, float):
            assert a == pytest.approx(float(b), rel=1e-12, abs=1e-9), f"{where}: {key}"
        else:
            assert a == b, f"{where}: {key} {a!r} != {b!r}"


def _fly_both(kwargs: dict, budgets, actions_of, steps: int = 40):
    """Step a batched env and N single envs with the same seeds, budgets and actions; compare
    every observation, reward, flag and info until each single episode ends. Returns how
    each episode ended (crash reason or "landed")."""
    n = len(budgets)
    seeds = [1000 + 7 * i for i in range(n)]
    venv = gym.make_vec("cpp_mujoco/MuJoCo-v0", num_envs=n, map=MAP, threads=2, **kwargs)
    assert isinstance(venv, MuJoCoVectorEnv)
    singles = [gym.make("cpp_mujoco/MuJoCo-v0", map=MAP, **kwargs).unwrapped for _ in range(n)]
    obs, info = venv.reset(seed=seeds, options={"budget": np.array(budgets)})
    for i, env in enumerate(singles):
        o, si = env.reset(seed=seeds[i], options={"budget": budgets[i]})
        _same(si, info, i, f"reset {i}")
        for key in o:
            np.testing.assert_array_equal(o[key], obs[key][i])
    ended: dict[int, str] = {}
    for step in range(steps):
        actions = actions_of(step, n)
        obs, reward, terminated, truncated, info = venv.step(actions)
        for i, env in enumerate(singles):
            if i in ended:
                continue
            o, r, term, trunc, si = env.step(int(actions[i]))
            where = f"step {step} env {i}"
            assert (r, term, trunc) == (reward[i], terminated[i], truncated[i]), where
            _same(si, info, i, where)
            for key in o:
                np.testing.assert_array_equal(o[key], obs[key][i], err_msg=where)
            if term:
                ended[i] = "landed" if si["landed"] else si["crash_reason"]
        if len(ended) == n:
            break
    venv.close()
    return ended


def test_batched_equals_single_envs_in_turbulent_wind_with_the_guard():
    """Rated wind and turbulence (each drone its own gusts from its own seed), the return
    guard taking over, landings at different times: cell, budget, energy, coverage, flags and
    every info key agree with N single envs to the last bit."""
    rng = np.random.default_rng(3)

    def actions(step, n):  # wander, and land now and then
        a = rng.integers(0, 4, size=n)
        return np.where(rng.random(n) < 0.12, 4, a)

    kwargs = {"wind_speed": 9.0, "wind_direction": 270.0, "turbulence": "moderate",
              "return_guard": True}  # fmt: skip
    ended = _fly_both(kwargs, [4, 6, 9, 12, 5], actions)
    assert len(ended) == 5
    assert "landed" in ended.values()


def test_a_gust_seed_flies_other_gusts_for_the_same_episodes_alike_in_both_envs():
    """``gust_seed`` > 0: the same starts and budgets meet other gust histories (energies
    differ from the episode's own gusts), the same in the batched and the single env; 0 is the
    episode's own generator, unchanged."""

    def actions(step, n):  # out and back, then land
        return np.full(n, (0, 2, 4)[min(step, 2)])

    wind = {"wind_speed": 9.0, "turbulence": "moderate"}

    def energies(**extra):
        env = gym.make("cpp_mujoco/MuJoCo-v0", map=MAP, **wind, **extra).unwrapped
        env.reset(seed=5, options={"start": (2, 2), "budget": 20})
        return [env.step(int(a))[4]["energy_used_j"] for a in actions(0, 1).tolist() * 2]

    own, again, held_out = energies(), energies(gust_seed=0), energies(gust_seed=1)
    assert own == again and own != held_out
    assert energies(gust_seed=1) == held_out  # a gust seed is a seed: reproducible
    ended = _fly_both({**wind, "gust_seed": 7}, [6, 9, 12], actions, steps=6)
    assert len(ended) == 3
    with pytest.raises(ValueError, match="gust_seed"):
        gym.make("cpp_mujoco/MuJoCo-v0", map=MAP, gust_seed=-1)


def test_batched_equals_single_envs_when_the_budget_runs_out():
    """A policy that never lands: emergency landings, budget exhaustion and hovers (rejected
    moves at the edge) end each episode exactly as in the single env."""
    rng = np.random.default_rng(11)
    ended = _fly_both({}, [3, 4, 6], lambda step, n: rng.integers(0, 4, size=n))
    assert len(ended) == 3
    assert set(ended.values()) <= {
        "budget exhausted before landing",
        "budget exhausted in flight: emergency landing where it was",
    }


def test_autoreset_draws_the_next_episode_as_a_single_env_reset_would():
    """NEXT_STEP autoreset: the step after an episode ends starts a new one from that env's
    generator — the episode a single env's plain ``reset()`` draws after the same history."""
    venv = MuJoCoVectorEnv(num_envs=2, map=MAP)
    single = gym.make("cpp_mujoco/MuJoCo-v0", map=MAP).unwrapped
    venv.reset(seed=[5, 6])
    single.reset(seed=5)
    _, _, terminated, _, _ = venv.step(np.array([4, 4]))  # both land at once
    single.step(4)
    assert terminated.all()
    obs, reward, terminated, _, info = venv.step(np.array([0, 0]))  # ignored: resets
    o, si = single.reset()
    assert not terminated.any() and (reward == 0).all()
    assert tuple(info["position"][0]) == tuple(si["position"])
    assert info["budget"][0] == si["budget"]
    np.testing.assert_array_equal(obs["budget"][0], o["budget"])
    venv.close()


def test_bad_options_fail_clearly():
    with pytest.raises(ValueError, match="num_envs"):
        MuJoCoVectorEnv(num_envs=0, map=MAP)
    with pytest.raises(ValueError, match="threads"):
        MuJoCoVectorEnv(num_envs=2, map=MAP, threads=0)
    with pytest.raises(ValueError, match="wind is flown"):
        MuJoCoVectorEnv(num_envs=2, map=MAP, wind=GridWind())
    with pytest.raises(TypeError, match="unknown option"):
        MuJoCoVectorEnv(num_envs=2, map=MAP, wind_sped=3)
    env = MuJoCoVectorEnv(num_envs=2, map=MAP)
    with pytest.raises(ValueError, match="seed list"):
        env.reset(seed=[1, 2, 3])
    with pytest.raises(ValueError, match="not a landing cell"):
        env.reset(seed=0, options={"start": np.array([[0, 0], [2, 1]])})
    with pytest.raises(NotImplementedError, match="checkpoint the policy"):
        env.state_dict()
    env.close()
