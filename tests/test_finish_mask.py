"""The finish mask: when a target is in reach, cell by cell; that it is the safe greedy planner's
own landing test; that it only drops the landing; that an episode flown with it covers at least
what it covers without, and still lands; results and configs name it."""

import numpy as np
import pytest

from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.map_pool import MapPool
from cpp_mujoco.agent.rules.finish_mask import FINISH_RULE, finish_allowed, targets_in_reach
from cpp_mujoco.cli.maps import agent_entry
from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.planners.safe_greedy import SafeGreedyPlanner
from cpp_mujoco.protocol.evaluate import evaluate
from tests.hand_observations import hand_observation

ALL = np.ones((1, 5), dtype=bool)


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """Batches of a few episodes gain nothing from a second torch thread, and on a shared
    2-core machine it slows them down: one thread."""


def _obs(landing=((2, 2),), **kwargs):
    return hand_observation(landing=landing, **kwargs)


def test_a_target_is_in_reach_only_if_the_way_there_and_home_is_paid():
    # the target (0, 4) is first seen from (1, 3): 2 moves from the landing cell (2, 2), then 2
    # moves back and the landing — 5 units in all
    assert targets_in_reach(_obs(budget=5, targets=[(0, 4)])).tolist() == [True]
    assert targets_in_reach(_obs(budget=4, targets=[(0, 4)])).tolist() == [False]
    # seen already, or behind a no-fly wall that makes the way longer than the budget
    assert not targets_in_reach(_obs(budget=30, targets=[(0, 4)], covered=[(0, 4)]))[0]
    wall = [(1, 1), (1, 2), (1, 3), (2, 3), (3, 3)]
    # round it: 7 moves to (0, 3) or (1, 4), 7 back and the landing
    assert not targets_in_reach(_obs(budget=14, targets=[(0, 4)], nfz=wall))[0]
    assert targets_in_reach(_obs(budget=15, targets=[(0, 4)], nfz=wall))[0]


def test_only_the_landing_is_dropped_and_a_row_never_loses_every_action():
    in_reach = _obs(budget=10, targets=[(0, 4)])
    assert finish_allowed(in_reach, ALL).tolist() == [[True, True, True, True, False]]
    seen = _obs(budget=10, targets=[(0, 4)], covered=[(0, 4)])  # nothing left to see
    assert finish_allowed(seen, ALL).tolist() == ALL.tolist()
    only_land = np.array([[False, False, False, False, True]])
    assert finish_allowed(in_reach, only_land).tolist() == only_land.tolist()
    # the revisit mask left only the landing: the moves it dropped come back instead
    wider = np.array([[True, False, True, False, True]])
    got = finish_allowed(in_reach, only_land, wider=wider)
    assert got.tolist() == [[True, False, True, False, False]]


def test_it_is_the_safe_greedy_planners_landing_test():
    """On a landing cell the planner lands exactly where the mask sees no target in reach."""
    pool = MapPool.generate((16,), 3, 2_000_100)
    rng = np.random.default_rng(0)
    planner, checked, per_map = SafeGreedyPlanner(), 0, []
    for grid_map in pool.maps:
        cells = np.flatnonzero(grid_map.landing.reshape(-1))
        n = 200
        h, w = grid_map.shape
        position = np.zeros((n, h * w), dtype=np.int8)
        position[np.arange(n), rng.choice(cells, n)] = 1
        coverage = (rng.random((n, h * w)) < rng.random((n, 1))).astype(np.int8)
        obs = {
            "map": np.stack([grid_map.landing, grid_map.target, grid_map.nfz]).astype(np.float32),
            "position": position.reshape(n, h, w),
            "coverage": coverage.reshape(n, h, w),
            "budget": rng.integers(1, 40, size=(n, 1)).astype(np.float32),
        }
        in_reach = targets_in_reach(obs)
        assert 0 < in_reach.sum() < n  # both kinds of state are drawn
        np.testing.assert_array_equal(planner.act(obs) == LAND, ~in_reach)
        # per-row maps (a batch of several maps) decide the same
        per_row = {**obs, "map": np.repeat(obs["map"][None], n, axis=0)}
        np.testing.assert_array_equal(targets_in_reach(per_row), in_reach)
        per_map.append((per_row, in_reach))
        checked += n
    assert checked == 600
    # rows of different maps in one batch: each row is decided on its own map
    mixed = {k: np.concatenate([obs[k] for obs, _ in per_map]) for k in per_map[0][0]}
    expected = np.concatenate([in_reach for _, in_reach in per_map])
    np.testing.assert_array_equal(targets_in_reach(mixed), expected)


@pytest.fixture(scope="module")
def general():
    return load_agent("general")


def test_an_episode_with_it_covers_at_least_as_much_and_still_lands(general):
    """A validation-range map on which the agent, unmasked, lands early at budget 75 (from two
    of its five landing cells, 54 of 56 targets seen: the mask flies on to all 56)."""
    pool = MapPool.generate((16,), 1, 2_000_107)
    grid_map, config = pool.maps[0], pool.configs[0]
    budgets = [50, 75]
    _, plain_agent = agent_entry("general", general, ["no-finish-mask"])
    plain = evaluate(plain_agent, grid_map, budgets=budgets, config=config)
    masked = evaluate(general, grid_map, budgets=budgets, config=config)
    assert general.finish_mask and not plain_agent.finish_mask
    assert masked.landing_ratio == plain.landing_ratio == 1.0
    np.testing.assert_array_equal(masked.budgets, plain.budgets)
    assert (masked.coverage >= plain.coverage - 1e-12).all()
    assert (masked.coverage > plain.coverage).sum() >= 2  # measured: 2 of the 10 episodes
    assert masked.steps.mean() > plain.steps.mean()
    assert masked.conditions["policy"]["finish_rule"] == FINISH_RULE
    assert not plain.conditions["policy"]["finish_mask"]


def test_configs_and_files_name_it(general):
    assert GeneralTrainConfig().finish_mask
    assert not GeneralTrainConfig.from_dict({}).finish_mask  # runs from before the option
    assert general.metadata["finish_mask"] and general.finish_mask
    assert not load_agent("A").finish_mask  # the paper's per-map agents fly without it
    label, _ = agent_entry("general", load_agent("general"), ["no-finish-mask"])
    assert label == "ddqn[general, rules: return-mask+revisit-mask+progress-mask]"
    assert agent_entry("general", load_agent("general"), ["+finish-mask"])[0] == "ddqn[general]"
