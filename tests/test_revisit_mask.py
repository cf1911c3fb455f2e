"""The revisit mask: which moves it drops, cell by cell; its memory per episode; that the bundled
general agent's cycles end with it; that batched and single episodes fly alike; results name it."""

import numpy as np
import pytest

from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.rules.revisit_mask import REVISIT_RULE, RevisitMemory
from cpp_mujoco.grid.actions import WEST
from cpp_mujoco.grid.env import GridEnv
from cpp_mujoco.map_sets.sets import load_map_set
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.protocol.episode import run_episode
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets
from scripts.agent_loops import longest_cycle_run
from tests.hand_observations import hand_observation

ALL = np.ones((1, 5), dtype=bool)


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """Batches of a few episodes gain nothing from a second torch thread, and on a shared
    2-core machine it slows them down: one thread."""


_obs = hand_observation


def test_a_move_back_into_a_fruitless_cell_is_dropped_cell_by_cell():
    memory = RevisitMemory()
    assert memory.allowed(_obs(cell=(2, 2), budget=30), ALL).all()  # nothing flown yet
    assert memory.allowed(_obs(cell=(2, 3), budget=29), ALL).tolist() == [
        [True, True, True, False, True]  # west leads back to (2, 2)
    ]
    # back at (2, 2): east leads to (2, 3), flown; the rest is new
    assert memory.allowed(_obs(cell=(2, 2), budget=28), ALL).tolist() == [
        [True, False, True, True, True]
    ]
    # a flown cell whose view now holds an unseen target is allowed again ((1, 4) is seen from
    # (2, 3)); landing is never dropped
    got = memory.allowed(_obs(cell=(2, 2), budget=27, targets=[(1, 4)]), ALL)
    assert got.tolist() == [[True, True, True, True, True]]


def test_hovers_count_as_revisits_and_the_fallback_keeps_the_allowed_set():
    memory = RevisitMemory()
    # in the corner (0, 0): north and west leave the map, east is a no-fly cell — all hover
    obs = _obs(cell=(0, 0), nfz=[(0, 1)])
    assert memory.allowed(obs, ALL).tolist() == [[False, False, True, False, True]]
    # the caller's set is only narrowed: an action it left out stays out
    only_moves = np.array([[True, True, False, True, False]])
    assert memory.allowed(obs, only_moves).tolist() == [[True, True, False, True, False]]


def test_the_memory_forgets_when_the_coverage_grows_or_an_episode_starts():
    memory = RevisitMemory()
    memory.allowed(_obs(cell=(2, 2), budget=30), ALL)
    assert not memory.allowed(_obs(cell=(2, 3), budget=29), ALL)[0, WEST]
    # a new cell seen: (2, 2) is a new state now
    grown = memory.allowed(_obs(cell=(2, 3), budget=28, covered=[(0, 0)]), ALL)
    assert grown[0, WEST]
    # a new episode without reset (the budget rose): forgotten too
    memory.allowed(_obs(cell=(2, 2), budget=27), ALL)
    assert memory.allowed(_obs(cell=(2, 3), budget=40), ALL)[0, WEST]
    memory.reset()
    assert memory.visited is None


@pytest.fixture(scope="module")
def general():
    return load_agent("general")


def test_the_bundled_general_agent_flies_with_it_and_results_name_it(general):
    assert general.revisit_mask and general.return_mask
    result = evaluate(general, "A", budgets=[40])
    policy = result.conditions["policy"]
    assert policy["revisit_mask"] and policy["revisit_rule"] == REVISIT_RULE
    assert not evaluate(load_agent("A"), "A", budgets=[40]).conditions["policy"]["revisit_mask"]
    assert not GeneralTrainConfig.from_dict({}).revisit_mask  # runs from before the option
    assert GeneralTrainConfig().revisit_mask


def test_it_ends_the_cycles_of_a_held_out_map(general):
    """gen16-s1000034 of heldout16-v1, every 10th budget: measured without the mask 0.618
    coverage, 44 of 90 episodes cycling for >= 10 steps; with it 0.749 and none."""
    grid_map = load_map_set("heldout16-v1", 35)[34]
    config = size_config(16)
    budgets = protocol_budgets(config, 10)
    own = [r for r in general.rule_names if r != "progress-mask"]  # it prunes loops too
    plain_agent = general.with_rules([r for r in own if r != "revisit-mask"])
    plain = evaluate(plain_agent, grid_map, budgets=budgets, config=config)
    masked = evaluate(general.with_rules(own), grid_map, budgets=budgets, config=config)
    cycles = [sum(longest_cycle_run(t) >= 10 for t in r.trajectories) for r in (plain, masked)]
    assert masked.landing_ratio == plain.landing_ratio == 1.0
    assert cycles[0] >= 20 and cycles[1] <= cycles[0] // 10
    assert masked.coverage_ratio > plain.coverage_ratio + 0.05


def test_single_and_batched_episodes_fly_alike(general):
    """The memory is per row: the batched protocol and one env at a time give the same paths."""
    grid_map = load_map_set("heldout16-v1", 35)[34]
    config = size_config(16)
    batched = evaluate(general, grid_map, budgets=[45, 75], config=config)
    env = GridEnv(grid_map, config)
    for i in range(0, len(batched.budgets), 3):
        start, budget = tuple(int(v) for v in batched.starts[i]), int(batched.budgets[i])
        record = run_episode(env, general, seed=i, options={"start": start, "budget": budget})
        want = batched.trajectories[i]
        assert record.cells == want[want >= 0].tolist()
