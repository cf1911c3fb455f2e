"""The bundled general agent (``load_agent("general")``): one network that acts on 16×16 and
32×32 observations, flies held-out maps home in every episode and covers far more than chance,
never saw a held-out or validation seed in training, and is what ``scripts/train_general.py``
makes."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from cpp_mujoco.agent import GENERAL_AGENT, load_agent
from cpp_mujoco.agent.checkpoint import CheckpointError, load_checkpoint
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.home_input import safe_actions
from cpp_mujoco.agent.map_pool import TRAIN_SEEDS, VALIDATION_SEEDS
from cpp_mujoco.agent.training_state import RESUMABLE_CHANGES
from cpp_mujoco.cli.main import build_parser
from cpp_mujoco.cli.train_general import config_from_args
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.map_sets.sets import heldout_set_of, load_map_set
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.maps import load_map
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "train_general.py"


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """A 1.2 M-parameter network on a shared 2-core machine: one torch thread."""


@pytest.fixture(scope="module")
def agent():
    return load_agent(GENERAL_AGENT)


def test_it_loads_by_name_and_acts_on_both_sizes(agent):
    assert agent.name == "ddqn-general" and agent.metadata["bundled"]
    assert agent.map_shape is None and agent.metadata["architecture"] == "general"
    assert agent.return_mask and agent.network.target_input
    for size in (16, 32):
        grid_map = load_map_set(f"heldout{size}-v1", first=1)[0]
        mdp = GridMDP(grid_map, 4, size_config(size))
        mdp.reset(np.random.default_rng(size))
        obs = mdp.observation()
        actions = agent.act(obs)
        assert actions.shape == (4,) and agent.act({k: v[1] for k, v in obs.items()}) == actions[1]
        safe = safe_actions(obs["map"], obs["position"], obs["budget"])
        assert safe[np.arange(4), actions].all()


@pytest.mark.parametrize("size", [16, 32])
def test_it_flies_an_unseen_map_home_and_covers(agent, size):
    """The first map of each held-out set, six budgets spanning its size class's range (every
    10th of 16×16's, every 20th of 32×32's): every episode lands, and it covers far more than
    the random policy and at least 70 % of what the safe greedy planner covers (measured:
    16×16 90.0 % against 91.1 %; 32×32 52.8 % against 51.4 %)."""
    grid_map, config = load_map_set(f"heldout{size}-v1", first=1)[0], size_config(size)
    budgets = protocol_budgets(config, {16: 10, 32: 20}[size])
    assert len(budgets) == 6
    ours = evaluate(agent, grid_map, budgets=budgets, config=config)
    rand = evaluate(make_planner("random"), grid_map, budgets=budgets, config=config)
    greedy = evaluate(make_planner("safe-greedy"), grid_map, budgets=budgets, config=config)
    assert ours.landing_ratio == 1.0
    assert ours.coverage_ratio > rand.coverage_ratio + 0.2
    assert ours.coverage_ratio > 0.7 * greedy.coverage_ratio


def test_it_never_trained_on_held_out_or_validation_maps(agent):
    state = load_checkpoint(agent.metadata["source"])
    first, last = state["train_maps"]["seeds"]
    assert TRAIN_SEEDS.start <= first <= last < TRAIN_SEEDS.stop
    first, last = state["validation_maps"]["seeds"]
    assert VALIDATION_SEEDS.start <= first <= last < VALIDATION_SEEDS.stop
    assert state["train_maps"]["sizes"] == [16, 32]
    # the maps it was given by name are the paper's A, B and C, none of a held-out set
    named = state["train_maps"].get("named", [])
    assert named == [f"{m} ({load_map(m).digest})" for m in "ABC"]
    assert all(heldout_set_of(entry.split("(")[1].rstrip(")")) is None for entry in named)


def test_it_is_what_the_training_script_makes(agent):
    spec = importlib.util.spec_from_file_location("train_general", SCRIPT)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    folder, argv = script.stage_commands(Path("runs/general"), [])[-1]
    expected = config_from_args(build_parser().parse_args(argv)).to_dict()
    stored = GeneralTrainConfig.from_dict(agent.metadata["config"]).to_dict()
    assert stored["init_from"] == expected["init_from"]  # the stage before, in the same --out
    assert Path(stored["init_from"]).parent.parent == folder.parent
    # every learning setting; the schedule-only ones (a time limit that did not bind, the
    # evaluation and checkpoint cadence, threads) may differ, as on a resume
    schedule = RESUMABLE_CHANGES - {"total_updates", "stop_after_updates"}
    assert {k: v for k, v in stored.items() if k not in schedule} == {
        k: v for k, v in expected.items() if k not in schedule
    }


def test_without_a_bundled_file_the_error_says_how_to_get_one(monkeypatch, tmp_path):
    import cpp_mujoco.agent as agent_package

    monkeypatch.setattr(agent_package, "BUNDLED_DIR", tmp_path)
    with pytest.raises(CheckpointError, match="no general agent is bundled.*train-general"):
        load_agent(GENERAL_AGENT)
