"""The bundled agents load by name, act on observations and still fly the protocol well."""

import numpy as np
import pytest

from cpp_mujoco.agent import GENERAL_AGENTS, bundled_agents, load_agent
from cpp_mujoco.agent.network import count_parameters
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.grid.wind import GridWind
from cpp_mujoco.maps import load_map
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.evaluate import PAPER_LANDING_RATIO, evaluate, protocol_budgets
from tests import bundled_protocol

NAMES = [n for n in bundled_agents() if not n.endswith("-wind") and n not in GENERAL_AGENTS]
WIND_NAMES = [n for n in bundled_agents() if n.endswith("-wind") and n not in GENERAL_AGENTS]


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
def test_bundled_agent_meets_the_bar(name):
    """Issue 3's bar on the full protocol: lands at least as often as the paper's agent (and in
    ≥ 99.9 % of episodes) and covers at least as much as the safe greedy planner. The agent's
    full protocol is the record of ``tests/bundled_protocol.py``; a fifth of it (every 5th budget,
    every landing cell) is flown again here and must give the recorded episodes. The tolerances
    allow a few near-tied Q-values to break differently on another CPU's float kernels."""
    agent = load_agent(name)
    recorded = bundled_protocol.load(name)
    assert str(recorded["agent_digest"]) == agent.metadata["digest"], (
        f"agent {name} is not the recorded one: {bundled_protocol.RECORD}"
    )
    greedy = evaluate(make_planner("safe-greedy"), name)
    assert str(recorded["map_digest"]) == greedy.grid_map.digest
    assert recorded["landed"].size == greedy.landed.size  # every episode of the protocol
    np.testing.assert_array_equal(recorded["budgets"], greedy.budgets)
    assert recorded["landed"].mean() >= max(PAPER_LANDING_RATIO[name], 0.999)
    assert recorded["coverage"].mean() >= greedy.coverage_ratio - 1e-3
    flown = evaluate(agent, name, budgets=protocol_budgets(step=5))
    again = np.isin(recorded["budgets"], flown.budgets)
    assert again.sum() == flown.landed.size > recorded["landed"].size // 6
    np.testing.assert_array_equal(recorded["budgets"][again], flown.budgets)
    assert flown.landed[recorded["landed"][again]].all()  # no recorded landing crashes now
    differ = (recorded["coverage"][again] != flown.coverage) | (
        recorded["steps"][again] != flown.steps
    )
    assert differ.sum() <= flown.landed.size // 100, f"{differ.sum()} episodes differ"
    assert abs(flown.coverage_ratio - recorded["coverage"][again].mean()) < 1e-3


def test_every_bundled_map_has_a_wind_robust_agent_beside_its_paper_agent():
    assert WIND_NAMES == [f"{n}-wind" for n in NAMES]


@pytest.mark.parametrize("name", WIND_NAMES)
def test_wind_agent_reads_the_wind_and_lands_where_the_paper_agent_crashes(name):
    """A wind-robust agent's network reads budget and wind. In the grid's wind option at 9 m/s
    (N/E/S/W, gusts) it lands in ≥ 99 % of the full protocol where the paper agent of its map
    lands in 43–65 % (measured: 99.78 / 99.75 / 100 % on A / B / C; all three were fine-tuned in
    MuJoCo, whose moves cost less than the grid model's, and judged there: docs/agent.md), and
    in the paper's calm MDP it still lands in ≥ 99.5 % (measured: 100 % on each). Here the wind
    agent flies every 3rd budget of the protocol (every landing cell, every wind direction), the
    paper agent and the calm check every 5th."""
    agent = load_agent(name)
    grid_name = name.removesuffix("-wind")
    assert agent.network.wind_inputs and agent.metadata["map"] == grid_name
    assert agent.metadata["config"]["wind_max_speed"] > 0
    windy = GridConfig(wind=GridWind(min_speed=9.0, max_speed=9.0, calm_fraction=0.0))
    robust = evaluate(agent, grid_name, config=windy, budgets=protocol_budgets(windy, 3))
    some = protocol_budgets(windy, 5)
    paper = evaluate(load_agent(grid_name), grid_name, config=windy, budgets=some)
    assert robust.landing_ratio >= 0.99 and robust.landing_ratio >= paper.landing_ratio + 0.3
    assert evaluate(agent, grid_name, budgets=some).landing_ratio >= 0.995


def test_results_script_writes_table_and_figures(tmp_path):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "scripts" / "results.py"
    spec = importlib.util.spec_from_file_location("results_script", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    # the table and figures are under test (the bar on the full protocol: above), every 10th budget
    assert script.main(["--maps", "C", "--out", str(tmp_path), "--budget-step", "10"]) == 0
    table = (tmp_path / "results.txt").read_text()
    assert "98.26%" in table and "bar met" in table  # the paper's landing ratio for C
    names = {p.name for p in tmp_path.iterdir()}
    assert "grid_C_coverage.png" in names
    for policy in ("ddqn", "safe-greedy", "beam-search"):
        assert f"grid_C_{policy}_trajectories.png" in names
        assert f"grid_C_{policy}.json" in names
