"""The transition rules exist once (``GridMDP.apply``) and the single envs share one base.

Both backends turn an action into an :class:`Outcome` — the grid by the safety controller and
the square field of view, physics by flying it — and hand it to the same rules; these tests
pin that down, and what the shared base guarantees to both envs.
"""

import gymnasium as gym
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.grid.env import GridEnv
from cpp_mujoco.grid.mdp import GridMDP, Outcome, Rewards
from cpp_mujoco.grid.single_env import SingleGridEnv
from cpp_mujoco.grid.vector_env import GridVectorEnv
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.envs.single import MuJoCoEnv

SMALL = GridMap.from_ascii(["LTT", "TNT", "TTL"], name="small")
R = Rewards()


@pytest.fixture(scope="module")
def physics():
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL).unwrapped
    yield env
    env.close()


def _outcome(cell=0, rejected=False, landed=False, spent=1, newly_seen=0, failed=None):
    return Outcome(
        next_cell=np.array([cell]),
        rejected=np.array([rejected]),
        landed=np.array([landed]),
        spent=np.array([spent]),
        newly_seen=np.array([newly_seen]),
        failed=None if failed is None else np.array([failed]),
    )


def _mdp(budget: int) -> GridMDP:
    mdp = GridMDP(SMALL, 1)
    mdp.reset(np.random.default_rng(0), start=(0, 0), budget=budget)
    return mdp


@pytest.mark.parametrize(
    "budget, outcome, reward, terminated, crashed",
    [
        (5, dict(cell=1, newly_seen=2), 2 * R.coverage + R.move, False, False),
        (5, dict(rejected=True, newly_seen=1), R.coverage + R.move + R.safety, False, False),
        (1, dict(cell=1), R.move + R.crash, True, True),  # last unit spent, not landed
        (1, dict(landed=True), R.move, True, False),  # landing with the last unit
        (5, dict(spent=3), R.move, False, False),  # physics: one action may cost 3 units
        (2, dict(spent=3), R.move + R.crash, True, True),  # … and overdraw the budget
        (5, dict(cell=1, failed=True), R.move + R.crash, True, True),  # flipped, budget left
    ],
)
def test_apply_gives_reward_and_flags_for_an_outcome(budget, outcome, reward, terminated, crashed):
    mdp = _mdp(budget)
    out = mdp.apply(_outcome(**outcome))
    assert out.reward[0] == pytest.approx(reward)
    assert out.terminated[0] == terminated and out.crashed[0] == crashed
    assert mdp.done[0] == terminated and mdp.crashed[0] == crashed
    assert mdp.position[0] == outcome.get("cell", 0)
    assert mdp.budget[0] == budget - outcome.get("spent", 1)
    assert mdp.rejected[0] == outcome.get("rejected", False)  # the next observation's flag


def test_grid_step_and_physics_step_both_end_in_apply(physics, monkeypatch):
    calls = []
    apply = GridMDP.apply

    def spy(self, outcome, active=None):
        calls.append(outcome)
        return apply(self, outcome, active)

    monkeypatch.setattr(GridMDP, "apply", spy)
    grid = GridEnv(map=SMALL)
    for env in (grid, physics):
        calls.clear()
        env.reset(seed=0, options={"start": (0, 0), "budget": 9})
        env.step(1)  # east: accepted
        env.step(2)  # south into the no-fly cell: rejected
        assert [bool(o.rejected[0]) for o in calls] == [False, True]
        assert [int(o.next_cell[0]) for o in calls] == [1, 1]


def test_physics_reward_and_flags_equal_the_grid_rules_for_the_same_outcome(physics):
    """Fly until the budget runs out; replay each flown outcome through a grid MDP."""
    obs, info = physics.reset(seed=0, options={"start": (0, 0), "budget": 3})
    mdp = _mdp(3)
    for action in (1, 2, 1, 0):  # east, rejected south, east, north: the budget runs out
        seen_before = mdp.seen_targets[0]
        obs, reward, terminated, _, after = physics.step(action)
        newly_seen = round(after["coverage_ratio"] * mdp.num_targets) - seen_before
        row, col = after["position"]
        out = mdp.apply(
            _outcome(
                cell=row * mdp.width + col,
                rejected=after["rejected"],
                landed=after["landed"],
                spent=info["budget"] - after["budget"],
                newly_seen=newly_seen,
            )
        )
        assert reward == pytest.approx(float(out.reward[0]))
        assert terminated == bool(out.terminated[0])
        assert after["crashed"] == bool(out.crashed[0])
        np.testing.assert_array_equal(obs["budget"], mdp.observation_of(0)["budget"])
        np.testing.assert_array_equal(obs["safety"], mdp.observation_of(0)["safety"])
        info = after
        if terminated:
            break
    assert terminated and after["crashed"] and after["crash_reason"]


def test_a_physical_failure_ends_the_episode_through_the_same_rules(physics, monkeypatch):
    physics.reset(seed=0, options={"start": (0, 0), "budget": 9})
    fly = physics.flight.fly

    def flipped(kinds, cells, active):  # the flight as it flies, ending in a flip
        result = fly(kinds, cells, active)
        result["failure"][0], result["landed"][0] = "flipped over", False
        result["newly_seen"][0] = 0
        return result

    monkeypatch.setattr(physics.flight, "fly", flipped)
    _, reward, terminated, _, info = physics.step(1)
    assert terminated and info["crashed"] and info["crash_reason"] == "flipped over"
    assert info["budget"] > 0  # ended by the failure, not by the budget
    assert reward == pytest.approx(R.move + R.crash)
    assert physics.mdp.done[0]  # the MDP's own view agrees that the episode is over
    with pytest.raises(RuntimeError, match="call reset"):
        physics.step(1)


# ----------------------------------------------------------------------------- the shared base
def test_both_single_envs_share_the_base():
    assert issubclass(GridEnv, SingleGridEnv) and issubclass(MuJoCoEnv, SingleGridEnv)
    for name in ("reset", "step"):
        assert getattr(GridEnv, name) is getattr(SingleGridEnv, name)
        assert getattr(MuJoCoEnv, name) is getattr(SingleGridEnv, name)


@pytest.mark.parametrize("options", ["start", [("start", (0, 0))], 3])
def test_reset_options_must_be_a_dict_in_all_three_envs(physics, options):
    for env in (GridEnv(map=SMALL), physics, GridVectorEnv(num_envs=2, map=SMALL)):
        with pytest.raises(ValueError, match="reset options must be a dict"):
            env.reset(seed=0, options=options)


def test_unknown_reset_options_are_refused_alike(physics):
    messages = []
    for env in (GridEnv(map=SMALL), physics, GridVectorEnv(num_envs=2, map=SMALL)):
        with pytest.raises(ValueError, match=r"unknown reset option\(s\) \['strat'\]") as exc:
            env.reset(options={"strat": (0, 0)})
        messages.append(str(exc.value))
    assert messages[0] == messages[1]
    assert messages[2] == messages[0] + ", reset_mask"


def test_a_failed_backend_reset_leaves_the_env_needing_a_reset(physics, monkeypatch):
    physics.reset(seed=0, options={"start": (0, 0), "budget": 9})
    physics.step(1)  # mid-episode

    def broken(*args, **kwargs):
        raise RuntimeError("simulator refused the start state")

    monkeypatch.setattr(physics.flight, "reset", broken)
    with pytest.raises(RuntimeError, match="simulator refused"):
        physics.reset(seed=1, options={"start": (2, 2)})
    with pytest.raises(RuntimeError, match="call reset"):  # not a step on a half-reset env
        physics.step(1)
