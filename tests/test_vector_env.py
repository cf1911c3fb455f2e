"""The native batched env: gymnasium's vector API; step-by-step agreement with the single env."""

import gymnasium as gym
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401
from cpp_mujoco.grid.vector_env import GridVectorEnv
from cpp_mujoco.maps import GridMap

INFO_KEYS = ("position", "budget", "landed", "crashed", "rejected", "coverage_ratio")
SMALL_MAP = GridMap.from_ascii(["LTT", "TNT", "TTL"], name="small")


def test_make_vec_returns_the_native_array_env():
    envs = gym.make_vec("cpp_mujoco/Grid-v0", num_envs=8, map="B")
    assert isinstance(envs.unwrapped, GridVectorEnv)
    obs, info = envs.reset(seed=0)
    assert obs["coverage"].shape == (8, 16, 16) and obs["map"].shape == (8, 3, 16, 16)
    assert envs.observation_space.contains(obs)
    assert info["_budget"].all()


@pytest.mark.parametrize("map_name", ["A", "B", "C"])
def test_single_and_batched_envs_agree_step_by_step(map_name):
    n, steps = 8, 200
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


# ----------------------------------------------------------------------------- state_dict
def _run(envs, actions):
    out = []
    for a in actions:
        obs, reward, terminated, _, info = envs.step(a)
        out.append((obs, reward.copy(), terminated.copy(), info))
    return out


def test_state_dict_round_trip_continues_exactly():
    """Mid-run, with some envs waiting for their autoreset: a fresh env loaded from the state
    sees the same observations, rewards, flags and the same newly drawn episodes."""
    rng = np.random.default_rng(0)
    actions = rng.integers(5, size=(40, 6))
    envs = GridVectorEnv(num_envs=6, map="C", min_budget=2, max_budget=6)
    envs.reset(seed=5)
    _run(envs, actions[:7])
    state = envs.state_dict()
    assert state["pending_reset"].any()  # the state holds envs about to reset
    expected = _run(envs, actions[7:])
    assert envs.state_dict()["budget"] is not state["budget"]  # a copy, not the live array

    other = GridVectorEnv(num_envs=6, map="C", min_budget=2, max_budget=6)
    other.reset(seed=99)  # another position, budget and generator state entirely
    other.load_state_dict(state)
    got = _run(other, actions[7:])
    for (eo, er, et, ei), (go, gr, gt, gi) in zip(expected, got, strict=True):
        np.testing.assert_array_equal(er, gr)
        np.testing.assert_array_equal(et, gt)
        for key in eo:
            np.testing.assert_array_equal(eo[key], go[key], err_msg=key)
        for key in INFO_KEYS:
            np.testing.assert_array_equal(ei[key], gi[key], err_msg=key)


def test_state_dict_holds_every_per_env_array_of_the_mdp():
    """A state array added to the MDP but left out of its state would resume silently wrong."""
    envs = GridVectorEnv(num_envs=7, map=SMALL_MAP)  # 7: no other size of the 3x3 map's MDP
    envs.reset(seed=0)
    mdp = envs.unwrapped.mdp
    per_env = {k for k, v in vars(mdp).items() if isinstance(v, np.ndarray) and v.shape[:1] == (7,)}
    per_env -= {"_rows", "_map_view"}  # constants of the batch, not state
    assert per_env == set(mdp.STATE)
    assert set(envs.state_dict()) == set(mdp.STATE) | {"pending_reset", "rng"}


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda s: s.pop("coverage"), "lacks 'coverage'"),
        (lambda s: s.update(steps=np.zeros(4)), r"unknown env state entries \['steps'\]"),
        (lambda s: s.update(budget=np.zeros(3, np.int64)), "'budget' is int64\\[3\\]"),
        (lambda s: s.update(rng=s["rng"][:2]), "2 generator state"),
        (lambda s: s.update(pending_reset=np.zeros(4)), "'pending_reset'"),
    ],
    ids=["missing", "unknown", "other-num-envs", "generators", "pending-dtype"],
)
def test_load_state_dict_refuses_a_state_that_does_not_fit_and_changes_nothing(edit, match):
    source = GridVectorEnv(num_envs=4, map="C")
    source.reset(seed=1)
    state = source.state_dict()
    edit(state)
    envs = GridVectorEnv(num_envs=4, map="C")
    envs.reset(seed=2)
    before = envs.state_dict()
    with pytest.raises(ValueError, match=match):
        envs.load_state_dict(state)
    after = envs.state_dict()
    for key, value in before.items():
        if key == "rng":
            assert after[key] == value
        else:
            np.testing.assert_array_equal(after[key], value, err_msg=key)


def test_a_checkpoint_env_state_that_does_not_fit_is_a_checkpoint_error():
    import torch

    from cpp_mujoco.agent.checkpoint import CheckpointError
    from cpp_mujoco.agent.training_state import load_env_state

    three = GridVectorEnv(num_envs=3, map="C")
    three.reset(seed=0)
    saved = {k: torch.from_numpy(v) if isinstance(v, np.ndarray) else v
             for k, v in three.state_dict().items()}  # fmt: skip
    four = GridVectorEnv(num_envs=4, map="C")
    with pytest.raises(CheckpointError, match="environment state does not fit"):
        load_env_state(four, saved)
    other = GridVectorEnv(num_envs=3, map="C")
    load_env_state(other, saved)  # as a training checkpoint stores it: tensors in, arrays out
    np.testing.assert_array_equal(other.state_dict()["coverage"], three.state_dict()["coverage"])
