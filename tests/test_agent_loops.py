"""scripts/agent_loops.py: the longest hover or back-and-forth run in a trajectory, and the
script's report on a map set."""

import importlib.util
import json
from pathlib import Path

import numpy as np

from cpp_mujoco.protocol.evaluate import protocol_budgets

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "agent_loops.py"
spec = importlib.util.spec_from_file_location("agent_loops", SCRIPT)
agent_loops = importlib.util.module_from_spec(spec)
spec.loader.exec_module(agent_loops)


def test_the_longest_cycle_run():
    run = agent_loops.longest_cycle_run
    assert run(np.array([1, 2, 3, 4, -1, -1])) == 0  # a straight flight
    assert run(np.array([1, 2, 1, 2, 1, 2, 3, -1])) == 4  # a back-and-forth, then on
    assert run(np.array([5, 5, 5, 5, 5])) == 3  # a hover
    assert run(np.array([1, 2, 1, 9, 8, 9, 8, 9, 8, 9, 7])) == 5  # the longer of two runs
    assert run(np.array([3, -1])) == 0


def test_the_report_names_its_set_policy_and_counts(capsys, monkeypatch):
    # the report is under test, not the agent: it flies every 10th budget of the size class
    evaluate, flown = agent_loops.evaluate, []

    def some_budgets(agent, grid_map, config):
        flown.append(evaluate(agent, grid_map, config=config, budgets=protocol_budgets(config, 10)))
        return flown[-1]

    monkeypatch.setattr(agent_loops, "evaluate", some_budgets)
    argv = ["--map-set", "heldout16-v1", "--first", "1", "--agent", "general"]
    assert agent_loops.main(argv) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["map_set"]["name"] == "heldout16-v1" and report["map_set"]["evaluated"] == 1
    assert report["policy"] == "ddqn-general" and report["digest"]
    assert 0 <= report["cycling_episodes"] <= report["episodes"] == flown[0].landed.size > 0
    assert report["worst_maps"][0]["map"] == "gen16-s1000000"
