"""The bundled agents load by name, act on observations and still fly the protocol well."""

import numpy as np
import pytest

from cpp_mujoco.agent import bundled_agents, load_agent
from cpp_mujoco.agent.network import count_parameters
from cpp_mujoco.evaluate import evaluate
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.maps import load_map

NAMES = bundled_agents()


def test_some_agents_are_bundled():
    assert NAMES, "no bundled agents in cpp_mujoco/agent/bundled"


@pytest.mark.parametrize("name", NAMES)
def test_bundled_agent_loads_and_acts(name):
    agent = load_agent(name)
    assert count_parameters(agent.network) == 1_190_389
    assert agent.metadata["map"] == name
    mdp = GridMDP(load_map(name), 3)
    mdp.reset(np.random.default_rng(0))
    obs = mdp.observation()
    actions = agent.act(obs)
    assert actions.shape == (3,)
    assert agent.act({k: v[0] for k, v in obs.items()}) == actions[0]


@pytest.mark.parametrize("name", NAMES)
def test_bundled_agent_regression(name):
    # every landing cell × budgets 25, 35, …, 75 (the full protocol is in docs/agent.md)
    result = evaluate(load_agent(name), name, budgets=range(25, 76, 10))
    assert result.landing_ratio >= 0.9
    assert result.coverage_ratio >= 0.7
