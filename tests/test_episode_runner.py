"""One episode loop behind the protocol, ``fly`` and the rollouts; one protocol-budget rule; the
actions named in one place; a physics run in this process leaves torch's threads as it found them.
"""

import numpy as np
import pytest
import torch

from cpp_mujoco.grid.actions import ACTION_NAMES, NUM_ACTIONS
from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.maps import GridMap
from cpp_mujoco.missions.mission import fly_mission
from cpp_mujoco.planners import BeamSearchPlanner, SafeGreedyPlanner
from cpp_mujoco.planners.rollout import rollout
from cpp_mujoco.protocol.episode import run_episode
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets
from cpp_mujoco.protocol.physics_tasks import make_env

TINY = GridMap.from_ascii(["LT.", "..L"], name="tiny")
SMALL = GridMap.from_ascii(["LL.TT", "LL.TT", "....."], name="small")


def test_fly_the_protocol_and_a_rollout_play_the_same_episode():
    start, budget = (0, 1), 8
    width = SMALL.shape[1]
    planner = BeamSearchPlanner()
    mission = fly_mission(planner, SMALL, budget=budget, start=start, backend="grid")
    result = evaluate(planner, SMALL, budgets=[budget])
    i = next(i for i, s in enumerate(result.starts) if tuple(s) == start)
    cells = result.trajectories[i][result.trajectories[i] >= 0]
    assert result.steps[i] == mission.steps and result.returns[i] == mission.total_reward
    assert cells[0] == start[0] * width + start[1] and len(cells) == mission.steps + 1
    coverage = np.zeros((1, SMALL.landing.size), dtype=bool)
    actions, _, steps = rollout(SMALL, planner, np.array([cells[0]]), np.array([budget]), coverage)
    assert actions[0, : steps[0]].tolist() == mission.actions


def test_physics_protocol_episode_is_run_episode_with_the_episode_seed():
    result = evaluate(SafeGreedyPlanner(), TINY, backend="mujoco", budgets=[4], workers=1)
    env = make_env(TINY, {})
    for i, start in enumerate(result.starts):
        options = {"start": tuple(int(v) for v in start), "budget": 4}
        record = run_episode(env, SafeGreedyPlanner(), seed=i, options=options)
        assert record.cells == result.trajectories[i][: record.steps + 1].tolist()
        assert record.total_reward == result.returns[i]
        assert record.info["energy_used_j"] == result.physics["energy_used_j"][i]


def test_run_episode_hooks_see_the_start_and_every_step():
    env = make_env(TINY, {})
    seen = []
    record = run_episode(
        env, SafeGreedyPlanner(), seed=0, options={"start": (0, 0), "budget": 4},
        on_start=lambda obs, info: seen.append(("start", info["position"])),
        on_step=lambda action, obs, reward, info: seen.append((action, reward)),
    )  # fmt: skip
    assert seen[0] == ("start", (0, 0)) and record.start == (0, 0) and record.budget == 4
    assert [a for a, _ in seen[1:]] == record.actions
    assert sum(r for _, r in seen[1:]) == pytest.approx(record.total_reward)


class TwoActions(SafeGreedyPlanner):
    """Answers every batch with one action too many."""

    def act(self, obs):
        return np.append(super().act(obs), 0)


def test_a_policy_that_answers_with_the_wrong_number_of_actions_is_an_error():
    # before: a batch of one took the first action of several, silently
    with pytest.raises(ValueError, match="2 actions for one observation"):
        fly_mission(TwoActions(), SMALL, budget=6, start=(0, 1), backend="grid")
    with pytest.raises(ValueError, match="actions for"):
        evaluate(TwoActions(), SMALL, budgets=[6])


class ThreadsSeen(SafeGreedyPlanner):
    def __init__(self):
        super().__init__()
        self.threads = set()

    def act(self, obs):
        self.threads.add(torch.get_num_threads())
        return super().act(obs)


def test_physics_run_in_this_process_restores_torch_threads():
    before = torch.get_num_threads()
    torch.set_num_threads(3)
    try:
        policy = ThreadsSeen()
        evaluate(policy, TINY, backend="mujoco", budgets=[3], workers=1)
        assert policy.threads == {1}  # one thread while flying, as in a worker process
        assert torch.get_num_threads() == 3  # the caller's count is back
    finally:
        torch.set_num_threads(before)


def test_protocol_budgets_are_one_rule():
    assert protocol_budgets() == list(range(25, 76))
    assert protocol_budgets(step=5) == list(range(25, 76, 5))
    assert protocol_budgets(GridConfig(min_budget=8, max_budget=16), 3) == [8, 11, 14, 16]
    with pytest.raises(ValueError, match="budget step"):
        protocol_budgets(step=0)
    result = evaluate(SafeGreedyPlanner(), TINY, config=GridConfig(min_budget=3, max_budget=5))
    assert sorted(set(result.budgets.tolist())) == [3, 4, 5]


def test_actions_are_named_once_and_the_network_outputs_one_q_value_each():
    from cpp_mujoco.agent.network import QNetwork

    assert NUM_ACTIONS == len(ACTION_NAMES) == 5
    assert QNetwork(4, 4).head[-1].out_features == NUM_ACTIONS
