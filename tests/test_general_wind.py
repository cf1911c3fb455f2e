"""The general agent in the grid's wind option: the return rule priced at the observed wind, the
calm network widened for the wind inputs, and a wind run whose files, validation and results say
which wind and which margin they were made with."""

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from cpp_mujoco.agent import CheckpointError, load_agent
from cpp_mujoco.agent.checkpoint import atomic_save, load_checkpoint
from cpp_mujoco.agent.demonstrations import record_demonstrations
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_network import GeneralQNetwork, widen_for_wind_inputs
from cpp_mujoco.agent.general_training import general_parts, initial_general_weights
from cpp_mujoco.agent.home_input import safe_actions
from cpp_mujoco.agent.map_pool import MapPool, padded_cell
from cpp_mujoco.agent.network import observation_to_tensors
from cpp_mujoco.agent.policy import GreedyAgent
from cpp_mujoco.agent.rules import ReturnMask
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.grid.graph import REJECTED_AFTER, build_graph
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.grid.return_rule import paid_actions, wind_allowance
from cpp_mujoco.grid.way_home import ReturnMargin, correlation_widening
from cpp_mujoco.grid.wind import KIND_INDEX, GridWind, wind_costs
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets
from cpp_mujoco.review.map_set_figures import merge_map_set_results, run_label
from tests.test_return_mask import SMALL_NET
from tests.test_return_mask import TINY as MASKED_TINY


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """Small nets on a shared 2-core machine: one torch thread."""


def _steady(speed: float) -> GridWind:
    return GridWind(min_speed=speed, max_speed=speed, calm_fraction=0.0)


# ------------------------------------------------------------------------------ the rule
def test_in_calm_air_the_rule_is_the_unit_cost_rule():
    rng = np.random.default_rng(0)
    after = rng.integers(0, 40, size=(500, 5))
    after[rng.random((500, 5)) < 0.1] = REJECTED_AFTER
    budget = rng.integers(0, 45, size=500)
    calm = after <= budget[:, None] - 1
    assert np.array_equal(paid_actions(after, budget), calm)
    assert np.array_equal(paid_actions(after, budget, np.zeros((500, 2))), calm)
    assert np.array_equal(paid_actions(after, budget, np.zeros((500, 2)), ReturnMargin()), calm)


def test_in_wind_a_move_is_paid_iff_the_priced_way_home_fits():
    """At 9 m/s from the north: units a move = the dearest moving kind's calibrated mean, the
    spread its gust σ widened by the correlation × the margin's sigmas, plus its reserve."""
    wind = np.array([[0.0, -9.0]])  # blowing towards the south (east, north m/s)
    table = wind_costs()
    mean, std, rho = table.at(np.array([9.0]))
    kinds = [KIND_INDEX[k] for k in ("upwind", "downwind", "crosswind")]
    sigmas, reserve = ReturnMargin().margin(9.0)
    units = mean[0, kinds].max()
    spread = std[0, kinds].max() * np.sqrt(correlation_widening(rho)[0]) * sigmas
    assert units > 1.3  # the upwind mean: dearer than a calm move
    got = wind_allowance(wind)
    assert np.allclose([got[0][0], got[1][0], got[2][0]], [units, spread, reserve])
    for moves in (1, 5, 20):
        needed = units * moves + 1 + spread * np.sqrt(moves) + reserve
        after = np.array([[moves, moves, moves, moves, 0]])
        below = paid_actions(after, np.array([needed - 1e-6]), wind)
        above = paid_actions(after, np.array([needed + 1e-6]), wind)
        assert below.tolist() == [[False] * 4 + [True]]  # a landing needs one unit only
        assert above.all()
    # a stronger wind never allows more (the same ways home, the same budgets); calm air has
    # no fallback for a spent budget (the invariant keeps one action paid), so rows where
    # calm air pays nothing are left out
    rng = np.random.default_rng(1)
    after, budget = rng.integers(0, 30, size=(400, 5)), rng.uniform(0, 60, size=400)
    previous = paid_actions(after, budget, np.zeros((400, 2)))
    after, budget, previous = (
        after[previous.any(1)],
        budget[previous.any(1)],
        previous[previous.any(1)],
    )
    for speed in (3.0, 6.0, 9.0, 12.0):
        now = paid_actions(after, budget, np.tile([speed, 0.0], (len(budget), 1)))
        assert not (now & ~previous).any()
        previous = now


def test_when_the_gusts_ate_the_margin_the_way_home_is_allowed():
    after = np.array([[7, 5, REJECTED_AFTER, 5, 9], [3, 4, 4, 2, 3]])
    paid = paid_actions(after, np.array([4.0, 2.5]), np.array([[0.0, -12.0], [12.0, 0.0]]))
    # nothing is paid: the actions nearest home, never a rejected one
    assert paid.tolist() == [[False, True, False, True, False], [False, False, False, True, False]]


def test_observation_pool_and_graph_price_the_same_rule():
    pool = MapPool.generate((16,), 1, 5).flown_with(_steady(9.0), ReturnMargin(gusty_sigmas=6.0))
    grid_map = pool.maps[0]
    mdp = GridMDP(grid_map, 64, pool.configs[0])
    mdp.reset(np.random.default_rng(3))
    obs = mdp.observation()
    assert np.hypot(*obs["wind"][0]) == pytest.approx(9.0)
    cells = obs["position"].reshape(64, -1).argmax(axis=1)
    budget = obs["budget"].reshape(-1) * np.linspace(0.2, 1.0, 64)  # spent budgets too
    after = build_graph(grid_map).home_after[cells]
    expect = paid_actions(after, budget, obs["wind"], pool.margin)
    got = safe_actions(obs["map"], obs["position"], budget, obs["wind"], pool.margin)
    assert np.array_equal(got, expect)
    padded = padded_cell(cells, grid_map.shape[1], pool.side)
    assert np.array_equal(pool.safe_actions(np.zeros(64, int), padded, budget, obs["wind"]), expect)
    assert not np.array_equal(got, paid_actions(after, budget))  # the wind counts
    assert not np.array_equal(got, paid_actions(after, budget, obs["wind"]))  # and the margin


# ------------------------------------------------------------------------------ widening
def test_a_calm_network_widened_for_the_wind_gives_the_same_values_in_any_wind():
    torch.manual_seed(0)
    calm = GeneralQNetwork(max_side=32, home_input=True, **SMALL_NET)
    windy = GeneralQNetwork(max_side=32, home_input=True, wind_inputs=True, **SMALL_NET)
    windy.load_state_dict(widen_for_wind_inputs(calm.state_dict(), windy))
    config = replace(size_config(16), wind=_steady(12.0))
    mdp = GridMDP(generate_from_seed(2_000_003, 16), 8, config)
    mdp.reset(np.random.default_rng(0))
    obs = mdp.observation()
    assert np.abs(obs["wind"]).max() > 0
    grid, scalars = observation_to_tensors(obs, 150.0, "cpu", False, True)
    grid_w, scalars_w = observation_to_tensors(obs, 150.0, "cpu", True, True)
    assert scalars_w.shape[1] == scalars.shape[1] + 3
    with torch.no_grad():
        assert torch.allclose(calm(grid, scalars), windy(grid_w, scalars_w), atol=1e-6)
    with pytest.raises(ValueError, match="inputs"):
        widen_for_wind_inputs(windy.state_dict(), windy)  # already wide


def test_an_untrained_masked_network_lands_in_strong_wind_where_unit_costs_crash():
    torch.manual_seed(0)
    net = GeneralQNetwork(max_side=32, home_input=True, wind_inputs=True, **SMALL_NET)
    grid_map, config = generate_from_seed(2_000_017, 16), size_config(16)
    budgets = protocol_budgets(config, 10)
    windy = replace(config, wind=_steady(12.0))
    masked = evaluate(GreedyAgent(net, 150.0, rules=[ReturnMask()]), grid_map, budgets=budgets,
                      config=windy)  # fmt: skip
    calm_rule = evaluate(make_planner("safe-greedy"), grid_map, budgets=budgets, config=windy)
    # measured: 0.986 (one gust tail in 72 episodes) against the calm planner's 0.069
    assert masked.landing_ratio >= 0.95 and calm_rule.landing_ratio < 0.5


# ------------------------------------------------------------------------------ a wind run
# the masked general run of test_return_mask, on 16×16 maps, in the wind option
TINY = {
    **MASKED_TINY, "sizes": (16,), "final_eval": True, "final_budget_step": 50,
    "demo_budget_step": 50, "wind_max_speed": 12.0, "wind_calm_fraction": 0.35,
    "guide": "safe-greedy-wind", "demo_planner": "beam-search-wind", "wind_planner_sigmas": 5.0,
}  # fmt: skip
CALM = {"wind_max_speed": 0.0, "guide": "safe-greedy", "demo_planner": "beam-search",
        "wind_planner_sigmas": 4.0}  # fmt: skip


@pytest.fixture(scope="module")
def wind_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("general-wind")
    trainer = Trainer(GeneralTrainConfig(total_updates=30, **TINY), out)
    trainer.run(progress=False)
    return out, trainer


def test_a_wind_run_flies_in_wind_and_masks_with_its_margin(wind_run):
    _, trainer = wind_run
    assert trainer.env.num_envs == 8 and trainer.maps.pool.wind == trainer.config.wind
    assert trainer.maps.val_pool.wind == trainer.config.wind
    assert trainer.maps.pool.margin.gusty_sigmas == 5.0
    replay, n = trainer.replay, trainer.replay.pos
    t, e = np.divmod(np.arange(n * replay.num_envs), replay.num_envs)
    winds = np.hypot(*replay.wind[t, e].T)
    assert (winds > 0).any() and (winds == 0).any() and winds.max() <= 12.0
    safe = replay._safe(t, e)
    taken = safe[np.arange(t.size), replay.action[t, e]]
    # the agent's own actions keep the mask; the guide (the first half of the envs here) prices
    # each heading itself, finer than the mask's heading-blind bound, and may fly outside it
    assert taken[e >= round(trainer.config.guide_fraction * trainer.config.num_envs)].all()
    assert trainer.demos is not None and np.abs(trainer.demos.wind).max() > 0


def test_a_wind_agent_file_observes_the_wind_and_results_name_its_margin(wind_run, tmp_path):
    out, trainer = wind_run
    agent = load_agent(out / "agent.pt")
    assert agent.network.wind_inputs and agent.return_mask
    assert agent.wind_margin == ReturnMargin(gusty_sigmas=5.0)
    config = replace(trainer.maps.pool.configs[0], wind=_steady(9.0))
    result = evaluate(agent, trainer.maps.pool.maps[0], budgets=[25], config=config)
    assert result.conditions["policy"]["wind_margin"]["gusty_sigmas"] == 5.0
    assert result.conditions["grid_config"]["wind"]["max_speed"] == 9.0
    final = json.loads((out / "final_eval.json").read_text())
    assert [p["policy"] for p in final["policies"]][1:] == ["safe-greedy-wind"]
    assert final["conditions"]["wind"]["max_speed"] == 12.0
    state = load_checkpoint(out / "agent.pt")
    state["config"]["wind_planner_sigmas"] = float("nan")
    atomic_save(state, tmp_path / "bad.pt")
    with pytest.raises(CheckpointError, match="wind_planner_sigmas"):
        load_agent(tmp_path / "bad.pt")


def test_a_wind_run_starts_from_a_calm_general_agent(wind_run, tmp_path):
    calm = Trainer(
        GeneralTrainConfig(total_updates=1, **{**TINY, "wind_max_speed": 0.0, "guide":
                           "safe-greedy", "demo_planner": "beam-search",
                           "wind_planner_sigmas": 4.0, "final_eval": False}),
        tmp_path / "calm",
    )  # fmt: skip
    calm.run(progress=False)
    config = GeneralTrainConfig(total_updates=1, init_from=str(tmp_path / "calm" / "agent.pt"),
                                **TINY)  # fmt: skip
    started = Trainer(
        config, tmp_path / "wind", general_parts(config, initial_general_weights(config))
    )
    obs = wind_run[1].env.observation()
    grid, scalars = observation_to_tensors(obs, 150.0, "cpu", False, True)
    grid_w, scalars_w = observation_to_tensors(obs, 150.0, "cpu", True, True)
    with torch.no_grad():
        assert torch.allclose(calm.online(grid, scalars), started.online(grid_w, scalars_w),
                              atol=1e-6)  # fmt: skip
    wind_file = GeneralTrainConfig(
        init_from=str(wind_run[0] / "agent.pt"),
        **{
            **TINY,
            "wind_max_speed": 0.0,
            "guide": "safe-greedy",
            "demo_planner": "beam-search",
            "wind_planner_sigmas": 4.0,
        },
    )
    with pytest.raises(CheckpointError, match="this run's network"):
        initial_general_weights(wind_file)  # a wind network into a calm run: refused


def test_demonstrations_keep_every_step_of_episodes_longer_than_the_budget():
    """At 3 m/s a move costs 0.95 units and a hover 0.91: an episode flies more steps than its
    budget (the memory was once sized for one unit a step and overflowed on 32×32 maps)."""
    grid_map = generate_from_seed(7, 32)
    config = replace(size_config(32), wind=_steady(3.0))

    def north(obs):  # north until the edge, then hovering there: never lands
        return np.zeros(np.shape(obs["coverage"])[0], dtype=np.int64)

    demo = record_demonstrations(grid_map, config, north, 3, 0.95, [150])
    flown = evaluate(north, grid_map, budgets=[150], config=config)
    actions = (flown.trajectories >= 0).sum(axis=1) - 1  # cells visited after the start
    assert actions.min() > 150 + 3 + 2 and len(demo) == actions.sum()
    assert demo.memory.action[demo.rows, demo.episodes].max() == 0


def test_demonstrations_fly_only_maps_up_to_demo_max_side(tmp_path):
    # which maps are flown is under test: the demonstrations fly two budgets of each (25, 75),
    # in calm air (the wind demonstrator's planning is not under test and costs more)
    config = GeneralTrainConfig(total_updates=1, **{**TINY, **CALM, "sizes": (16, 32),
                                "demo_max_side": 16, "named_maps": ("A",),
                                "named_share": 0.2})  # fmt: skip
    trainer = Trainer(config, tmp_path)
    flown = {int(m) for m in np.unique(trainer.demos.map_index)}
    assert flown == {0, 6}  # the first generated 16×16 map and the named A; not map 3, 32×32
    assert all(trainer.maps.pool.maps[m].shape == (16, 16) for m in flown)
    with pytest.raises(ValueError, match="demo_max_side"):
        GeneralTrainConfig(**{**TINY, "demo_max_side": 8})


def test_a_map_set_flies_in_the_grid_wind_and_its_file_says_so(tmp_path, capsys):
    from cpp_mujoco.cli.main import main

    argv = ["evaluate", "--map-set", "heldout16-v1", "--first", "1", "--budget-step", "50",
            "--planner", "safe-greedy", "safe-greedy-wind", "--out", str(tmp_path),
            "--no-progress"]  # fmt: skip
    assert main([*argv, "--grid-wind", "12"]) == 0
    assert "grid, wind 12 m/s from N/E/S/W" in capsys.readouterr().out
    result = json.loads((tmp_path / "grid-wind12_heldout16-v1_first1.json").read_text())
    wind = result["conditions"]["grid_config"]["wind"]
    assert wind["min_speed"] == wind["max_speed"] == 12.0 and wind["calm_fraction"] == 0.0
    landing = {p["policy"]: p["mean_landing_ratio"] for p in result["policies"]}
    assert landing["safe-greedy"] < 0.5 < landing["safe-greedy-wind"]  # unit costs crash
    assert main(argv) == 0  # calm air: its own file beside
    calm = json.loads((tmp_path / "grid_heldout16-v1_first1.json").read_text())
    assert calm["conditions"]["grid_config"]["wind"] is None
    # the figures say which air, and a calm and a windy run of one set are never drawn as one
    assert "wind 12 m/s, N/E/S/W" in run_label(result) and "wind" not in run_label(calm)
    with pytest.raises(ValueError, match="cannot merge"):
        merge_map_set_results([calm, result])
    capsys.readouterr()
    for bad, says in (
        (["--grid-wind", "nan"], "finite"),
        (["--grid-wind", "13"], "calibrated range"),
        (["--grid-wind", "9", "--backend", "mujoco"], "--wind-speed"),
    ):
        assert main([*argv, *bad]) == 2
        assert says in capsys.readouterr().err
    assert main(["evaluate", "--map", "A", "--grid-wind", "9"]) == 2
    assert "--grid-wind needs --map-set" in capsys.readouterr().err
