"""The bundled city agent (``load_agent("general-city")``): the general agent fine-tuned on city
maps, reading their obstacles; it flies a held-out city map home in every episode, never saw a
held-out or validation seed, and is what ``scripts/train_general.py --city`` makes."""

import importlib.util
from pathlib import Path

import pytest

from cpp_mujoco.agent import (
    BUNDLED_DIR,
    GENERAL_AGENT,
    GENERAL_AGENTS,
    GENERAL_CITY_AGENT,
    load_agent,
)
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.map_pool import TRAIN_SEEDS, VALIDATION_SEEDS
from cpp_mujoco.agent.training_state import RESUMABLE_CHANGES
from cpp_mujoco.cli.main import build_parser
from cpp_mujoco.cli.train_general import config_from_args
from cpp_mujoco.map_sets.sets import load_map_set
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.evaluate import evaluate

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "train_general.py"


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """A 1.2 M-parameter network on a shared 2-core machine: one torch thread."""


@pytest.fixture(scope="module")
def agent():
    return load_agent(GENERAL_CITY_AGENT)


def test_it_reads_obstacles_and_trained_on_city_maps_only(agent):
    assert GENERAL_CITY_AGENT in GENERAL_AGENTS and agent.metadata["bundled"]
    assert agent.name == "ddqn-general-city" and agent.reads_obstacles
    assert agent.rule_names == [
        "return-mask", "revisit-mask", "finish-mask", "progress-mask", "symmetric-q"
    ]  # fmt: skip
    assert agent.metadata["config"]["map_family"] == "city"
    first, last = agent.metadata["train_maps"]["seeds"]
    assert TRAIN_SEEDS.start <= first <= last < TRAIN_SEEDS.stop
    first, last = agent.metadata["validation_maps"]["seeds"]
    assert VALIDATION_SEEDS.start <= first <= last < VALIDATION_SEEDS.stop


def test_it_flies_a_held_out_city_map_home(agent):
    """The first map of city32-v1, three budgets of its size class: every episode lands and it
    covers at least 90 % of what safe greedy covers (measured: 50.6 % against 53.1 %)."""
    grid_map = load_map_set("city32-v1", first=1)[0]
    budgets = [60, 100, 140]
    mine = evaluate(agent, grid_map, budgets=budgets)
    greedy = evaluate(make_planner("safe-greedy"), grid_map, budgets=budgets)
    assert mine.landing_ratio == 1.0
    assert mine.coverage_ratio >= 0.9 * greedy.coverage_ratio


def test_the_plain_general_agent_still_refuses_city_maps():
    grid_map = load_map_set("city32-v1", first=1)[0]
    assert "obstacle" in (load_agent("general").fits(grid_map) or "")


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("train_general", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_it_is_what_the_training_script_makes(agent, script):
    folder, argv = script.stage_commands(Path("runs/general"), [], city=True)[-1]
    assert folder.name == "stage5-city"
    expected = config_from_args(build_parser().parse_args(argv)).to_dict()
    # --install adds the progress mask and the symmetric-Q rule to the city agent's file
    assert script.INSTALL_RULES[GENERAL_CITY_AGENT] == ("progress-mask", "symmetric-q")
    expected["symmetric_q"] = True
    stored = GeneralTrainConfig.from_dict(agent.metadata["config"]).to_dict()
    # the script starts from stage 4's best.pt, which is the bundled general agent
    assert expected["init_from"] == "runs/general/stage4/best.pt"
    assert Path(stored["init_from"]).resolve() == (BUNDLED_DIR / "general.pt").resolve()
    schedule = RESUMABLE_CHANGES - {"total_updates", "stop_after_updates"}
    ignore = schedule | {"init_from"}
    assert {k: v for k, v in stored.items() if k not in ignore} == {
        k: v for k, v in expected.items() if k not in ignore
    }
    with pytest.raises(ValueError, match="give one"):
        script.stage_commands(Path("runs/general"), [], wind=True, city=True)


def test_install_adds_rules_and_refuses_unknown_ones(script, tmp_path):
    source = BUNDLED_DIR / f"{GENERAL_CITY_AGENT}.pt"
    plain = tmp_path / "plain.pt"
    script.install(source, plain)
    assert load_agent(plain).rule_names == load_agent(source).rule_names
    general = tmp_path / "general.pt"
    script.install(BUNDLED_DIR / "general.pt", general, ("symmetric-q",))
    installed = load_agent(general)
    own = ["return-mask", "revisit-mask", "finish-mask", "progress-mask"]
    assert installed.rule_names == [*own, "symmetric-q"]
    assert installed.metadata["config"]["symmetric_q"] is True
    assert load_agent("general").rule_names == own
    # --install adds the progress mask to the general agent's file
    assert script.INSTALL_RULES[GENERAL_AGENT] == ("progress-mask",)
    with pytest.raises(ValueError, match="unknown rule 'look-ahead'"):
        script.install(source, tmp_path / "bad.pt", ("look-ahead",))
    assert not (tmp_path / "bad.pt").exists()
