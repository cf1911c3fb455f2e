"""Search with the learned values: the beam's whole-coverage bookkeeping, the agent as its
incumbent, and how results name it."""

import numpy as np
import pytest

from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_training import pool_demonstrations, training_pool
from cpp_mujoco.agent.policy import GreedyAgent
from cpp_mujoco.agent.value_beam import ValueBeamAgent, load_policy, make_demonstrator, split_search
from cpp_mujoco.cli.main import main
from cpp_mujoco.cli.maps import agent_entry
from cpp_mujoco.grid.actions import LAND, NUM_ACTIONS
from cpp_mujoco.grid.graph import build_graph
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.map_sets.sets import load_map_set
from cpp_mujoco.planners.beam_search import _pack, _unpack, plan_paths
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets
from cpp_mujoco.protocol.policy import policy_identity


def test_view_bits_hold_what_the_mdp_marks_from_every_cell():
    grid_map = load_map_set("city32-v1", first=1)[0]  # obstacles hide part of the square
    g = build_graph(grid_map)
    cells = np.flatnonzero(~grid_map.nfz.reshape(-1))
    mdp = GridMDP(grid_map, cells.size, GridConfig(fov_side=3))
    mdp.restore(cells, np.full(cells.size, 5), np.zeros((cells.size, g.num_cells), bool))
    mdp.step(np.full(cells.size, LAND))
    assert np.array_equal(_unpack(g.fov_view_bits[cells], g.num_cells), mdp.coverage)
    assert np.array_equal(_unpack(_pack(mdp.coverage), g.num_cells), mdp.coverage)


def test_the_values_read_each_path_s_whole_coverage():
    grid_map = load_map_set("heldout16-v1", first=1)[0]
    g = build_graph(grid_map)
    start = np.flatnonzero(grid_map.landing.reshape(-1))[:1]
    calls = []

    def values(cells, left, coverage):
        calls.append((cells.copy(), left.copy(), coverage.copy()))
        return np.zeros((cells.size, NUM_ACTIONS))

    plan_paths(g, start, np.array([30]), np.zeros((1, g.num_cells), bool), 8, values)
    assert calls[0][2].sum() == 0 and calls[0][1][0] == 30  # the start: nothing seen yet
    cells, left, coverage = calls[1]  # the paths one move on: each saw its cell's view
    mdp = GridMDP(grid_map, cells.size, GridConfig(fov_side=3))
    mdp.restore(np.repeat(start, cells.size), np.full(cells.size, 30), np.zeros_like(coverage))
    moves = np.array([next(a for a in range(LAND) if g.safety.next_cell[start[0], a] == c)
                      for c in cells])  # fmt: skip
    mdp.step(moves)
    assert np.array_equal(coverage, mdp.coverage) and (left == 29).all()
    assert len(calls) > 20  # read at every depth


@pytest.fixture(scope="module")
def general():
    return load_agent("general")


def test_the_search_lands_and_never_sees_less_than_its_agent(general):
    grid_map = load_map_set("heldout16-v1", first=1)[0]
    search = evaluate(ValueBeamAgent(general, width=8), grid_map, budgets=[30])
    alone = evaluate(general, grid_map, budgets=[30])
    assert search.landing_ratio == 1.0
    assert np.array_equal(search.starts, alone.starts)
    assert (search.coverage >= alone.coverage - 1e-12).all()
    assert search.coverage.mean() > alone.coverage.mean()  # it plans further than one step


def test_results_name_the_search_its_width_and_the_agent_s_rules(general):
    label, policy = agent_entry("general", general, None, 8)
    assert label == "ddqn[general]+value-beam[width 8]"
    identity = policy_identity(policy)
    assert identity["search"] == {"name": "value-beam", "width": 8}
    assert "progress_rule" in identity and identity["digest"] == general.metadata["digest"]
    label, _ = agent_entry("general", general, ["return-mask"], 32)
    assert label == "ddqn[general, rules: return-mask]+value-beam"


def test_a_spec_names_the_agent_and_whether_it_searches(general):
    """``general+value-beam`` is the bundled general policy: the agent ``general`` searching,
    named so in results exactly as ``--agent general --value-beam``."""
    assert split_search("general+value-beam") == ("general", True)
    assert split_search("runs/x/best.pt") == ("runs/x/best.pt", False)
    assert split_search("general+symmetric-q") == ("general+symmetric-q", False)
    policy = load_policy("general+value-beam")
    assert isinstance(policy, ValueBeamAgent) and policy.name == "ddqn-general+value-beam"
    assert policy.width == 32 and policy.map_shape is None
    assert isinstance(load_policy("general"), GreedyAgent)
    assert load_policy("A", width=8).map_shape == load_agent("A").map_shape is not None
    label, policy = agent_entry("general+value-beam", general, None)
    assert label == agent_entry("general", general, None, 32)[0] == "ddqn[general]+value-beam"
    assert policy_identity(policy)["search"] == {"name": "value-beam", "width": 32}


def test_the_command_line_flies_the_searching_policy(tmp_path, capsys):
    code = main(["fly", "--map", "C", "--agent", "general+value-beam", "--backend", "grid",
                 "--budget", "40"])  # fmt: skip
    assert code == 0 and "ddqn-general+value-beam" in capsys.readouterr().out
    # a per-map agent searching is still that map's agent only
    assert main(["fly", "--map", "B", "--agent", "A+value-beam", "--backend", "grid"]) == 2
    assert "trained on map 'A'" in capsys.readouterr().err


def test_a_per_map_agent_searches_only_its_map():
    search = ValueBeamAgent(load_agent("A"))
    assert search.fits(load_map_set("heldout16-v1", first=1)[0]) is not None


def test_an_agent_searching_with_its_values_teaches_a_general_run():
    """``demo_planner="general+value-beam"``: the demonstrations are the value beam's own
    missions (their coverage is its evaluation's on the same maps and budgets)."""
    config = GeneralTrainConfig(
        sizes=(16,), maps_per_size=2, demo_maps_per_size=1, demo_budget_step=25,
        demo_planner="general+value-beam", val_maps_per_size=1,
    )  # fmt: skip
    pool = training_pool(config)
    demos = pool_demonstrations(config, pool)
    teacher = make_demonstrator("general+value-beam")
    assert isinstance(teacher, ValueBeamAgent)
    flown = evaluate(teacher, pool.maps[0], budgets=protocol_budgets(pool.configs[0], 25))
    assert demos.coverage_ratio == flown.coverage_ratio and demos.landing_ratio == 1.0
    assert make_demonstrator("beam-search").name == "beam-search"
    with pytest.raises(ValueError, match="unknown planner"):
        make_demonstrator("beam-searh")
