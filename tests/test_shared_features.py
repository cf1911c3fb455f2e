"""A batch on one map reads each distinct grid once and gets the plain pass's Q-values bit for
bit; batches it cannot share take the plain pass."""

import numpy as np
import pytest

import cpp_mujoco.agent.policy as policy_module
from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.shared_features import _grid_keys, batch_rows, shared_q_values
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.map_sets.sets import load_map_set
from cpp_mujoco.maps import load_map


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """A shared 2-core machine: one torch thread."""


def _states(grid_map, rows: int, distinct: int, seed: int = 0) -> dict:
    """``rows`` observations on one map: ``distinct`` grids (cell, coverage), each repeated
    with other budgets, shuffled."""
    rng = np.random.default_rng(seed)
    free = np.flatnonzero(~grid_map.nfz.reshape(-1))
    cells = rng.choice(free, distinct)
    coverage = rng.random((distinct, grid_map.target.size)) < 0.4
    pick = rng.integers(distinct, size=rows)
    mdp = GridMDP(grid_map, rows, GridConfig(max_budget=150))
    mdp.restore(cells[pick], rng.integers(20, 150, size=rows), coverage[pick])
    return mdp.observation()


def _plain(agent, obs, monkeypatch):
    with monkeypatch.context() as patch:
        patch.setattr(policy_module, "shared_q_values", lambda *args: None)
        return agent.network_q_values(obs)


@pytest.mark.parametrize("agent_name,map_name", [("general", "gen32"), ("general-city", "city")])
def test_shared_features_give_the_plain_q_values_bit_for_bit(agent_name, map_name, monkeypatch):
    agent = load_agent(agent_name)
    grid_map = (
        load_map_set("city32-v1", first=1)[0] if map_name == "city" else generate_from_seed(7, 32)
    )
    obs = _states(grid_map, rows=264 * 2 + 7, distinct=300)  # ends in a chunk under 16 rows
    step = 264  # the chunk of a 63×63 canvas (policy.FORWARD_CELLS)
    shared = shared_q_values(agent, obs, step)
    assert shared is not None
    assert np.array_equal(shared, _plain(agent, obs, monkeypatch))
    assert np.array_equal(agent.network_q_values(obs), shared)  # the agent's own pass shares


def test_batches_that_cannot_share_take_the_plain_pass():
    agent = load_agent("general")
    obs = _states(generate_from_seed(3, 16), rows=40, distinct=10)
    per_row = {**obs, "map": np.array(obs["map"])}  # each row its own copy: maps may differ
    assert shared_q_values(agent, per_row, 264) is None
    assert shared_q_values(load_agent("A"), _states(load_map("A"), 40, 10), 264) is None
    assert shared_q_values(agent, batch_rows_of(obs, [0]), 264) is None  # one row


def batch_rows_of(obs: dict, rows: list[int]) -> dict:
    return {k: batch_rows(k, v, 0, None, np.asarray(rows)) for k, v in obs.items()}


def test_row_keys_are_equal_exactly_where_the_grids_are():
    obs = _states(generate_from_seed(3, 16), rows=60, distinct=12)
    keys = _grid_keys(obs)
    grids = np.concatenate([obs["coverage"].reshape(60, -1), obs["position"].reshape(60, -1)], 1)
    same_key = keys[:, None] == keys[None, :]
    same_grid = (grids[:, None] == grids[None, :]).all(-1)
    assert np.array_equal(same_key, same_grid) and same_grid.sum() > 60  # there are repeats
    wide = {**obs, "coverage": obs["coverage"].astype(np.float32) * 0.5}  # not 0/1: its bytes
    assert np.array_equal(_grid_keys(wide)[:, None] == _grid_keys(wide)[None, :], same_grid)


def test_rows_of_a_shared_map_stay_shared():
    obs = _states(generate_from_seed(3, 16), rows=8, distinct=3)
    part = batch_rows_of(obs, [1, 5, 6])
    assert part["map"].shape == (3, 3, 16, 16) and part["map"].strides[0] == 0
    assert np.array_equal(part["coverage"], obs["coverage"][[1, 5, 6]])
