"""The grid's power-variation option (``GridConfig(wind=GridWind(...))``): what each action costs
in the episode's wind, what the agent observes, the gust statistics against the calibration,
determinism under a seed (single and batched env alike) and the errors for bad options."""

import gymnasium as gym
import numpy as np
import pytest
import torch

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.network import QNetwork, observation_to_tensors
from cpp_mujoco.grid.actions import EAST, LAND, NORTH, SOUTH, WEST
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.grid.wind import (
    KIND_INDEX,
    MIN_COST_SHARE,
    GridWind,
    action_costs,
    gust_shape,
    wind_costs,
)
from cpp_mujoco.maps import GridMap

# 5×5, landing block in the middle column, no-fly cell in the north-east corner
OPEN = GridMap.from_ascii(["TTTTN", "TTTTT", "TTLTT", "TTLTT", "TTTTT"], name="open")
TABLE = wind_costs()


def steady(speed=9.0, frm="N", **kw) -> GridConfig:
    return GridConfig(
        wind=GridWind(min_speed=speed, max_speed=speed, calm_fraction=0.0, directions=(frm,), **kw)
    )


def mean_cost(kind: str, speed: float) -> float:
    row = list(TABLE.speeds).index(speed)
    return float(TABLE.mean[row, KIND_INDEX[kind]])


def test_each_action_costs_its_kind_in_a_steady_wind_from_the_north():
    env = gym.make("cpp_mujoco/Grid-v0", map=OPEN, config=steady(turbulence=False))
    obs, info = env.reset(seed=0, options={"start": (2, 2), "budget": 30})
    np.testing.assert_allclose(obs["wind"], [0.0, -9.0], atol=1e-5)  # the air moves south
    budget = 30.0
    m = env.unwrapped.mdp
    for action, kind in [
        (NORTH, "upwind"),  # (1,2): flying into a wind from the north
        (SOUTH, "downwind"),  # back to (2,2)
        (EAST, "crosswind"),  # (2,3)
        (WEST, "crosswind"),  # (2,2)
        (NORTH, "upwind"),  # (1,2)
        (NORTH, "upwind"),  # (0,2)
        (NORTH, "hover"),  # off the map: the safety controller rejects it, the UAV hovers
        (SOUTH, "downwind"),  # (1,2)
        (SOUTH, "downwind"),  # (2,2): landing cell
        (LAND, "land"),
    ]:
        obs, reward, terminated, _, info = env.step(action)
        budget -= mean_cost(kind, 9.0)
        assert m.budget[0] == pytest.approx(budget), kind
        assert obs["budget"][0] == np.floor(budget)  # observed in whole units
    assert terminated and info["landed"] and not info["crashed"]
    assert mean_cost("upwind", 9.0) > mean_cost("crosswind", 9.0) > mean_cost("downwind", 9.0)


def test_a_wind_from_another_side_turns_the_costs_with_it():
    env = gym.make("cpp_mujoco/Grid-v0", map=OPEN, config=steady(frm="E", turbulence=False))
    obs, _ = env.reset(seed=0, options={"start": (2, 2), "budget": 30})
    np.testing.assert_allclose(obs["wind"], [-9.0, 0.0], atol=1e-5)  # the air moves west
    env.step(EAST)
    assert env.unwrapped.mdp.budget[0] == pytest.approx(30 - mean_cost("upwind", 9.0))


def test_speeds_between_the_flown_ones_interpolate_linearly():
    mean, _, _ = TABLE.at(np.array([7.5]))
    lo, hi = mean_cost("upwind", 6.0), mean_cost("upwind", 9.0)
    assert mean[0, KIND_INDEX["upwind"]] == pytest.approx((lo + hi) / 2)


def test_under_one_unit_left_after_a_move_is_a_crash_and_a_landing_on_the_reserve_is_not():
    env = gym.make("cpp_mujoco/Grid-v0", map=OPEN, config=steady(turbulence=False))
    env.reset(seed=0, options={"start": (2, 2), "budget": 2})  # 2 − upwind 1.39 = 0.61 < 1
    _, reward, terminated, _, info = env.step(NORTH)
    assert terminated and info["crashed"] and info["budget"] == 0 and reward < -100
    env.reset(seed=0, options={"start": (2, 2), "budget": 2})
    env.step(SOUTH)  # downwind 1.09: 0.91 left, observed as 0 — and that is out of budget too
    assert env.unwrapped.mdp.crashed[0]
    env.reset(seed=0, options={"start": (2, 2), "budget": 1})
    _, _, terminated, _, info = env.step(LAND)  # the landing costs 0.84 of the last unit
    assert terminated and info["landed"] and not info["crashed"]


COLUMN = GridMap.from_ascii(["TLT"] + ["TTT"] * 7, name="column")  # 7 cells south of the start


def test_gust_costs_match_the_calibrated_mean_spread_correlation_and_skewness():
    """4000 episodes flying six cells downwind at 9 m/s: the sampled costs have the flown mean,
    spread and right tail (skewness), and consecutive costs the flown correlation."""
    n = 4000
    mdp = GridMDP(COLUMN, n, steady())
    mdp.reset(np.random.default_rng(1), budget=75)
    costs = []
    for _ in range(6):
        before = mdp.budget.copy()
        mdp.step(np.full(n, SOUTH))
        costs.append(before - mdp.budget)
    c = np.array(costs)  # (6, n), every one a downwind move
    row = list(TABLE.speeds).index(9.0)
    m, s = TABLE.mean[row, KIND_INDEX["downwind"]], TABLE.std[row, KIND_INDEX["downwind"]]
    assert c.mean() == pytest.approx(m, rel=0.03)
    assert c.std() == pytest.approx(s, rel=0.1)
    z = (c - c.mean()) / c.std()
    assert np.mean(z**3) == pytest.approx(TABLE.skewness[row], abs=0.3)
    assert TABLE.skewness[row] > 1.5  # far from a Gaussian's 0 and a log-normal's ≈ 0.8 here
    corr = np.corrcoef(c[:-1].ravel(), c[1:].ravel())[0, 1]
    assert corr == pytest.approx(TABLE.correlation[row], abs=0.05)


@pytest.mark.parametrize("skew, corr", [(0.0, 0.3), (0.33, 0.23), (2.07, 0.48), (2.75, 0.39)])
def test_the_gust_shape_solves_the_skewness_and_correlation_it_is_given(skew, corr):
    """z = a·g + b·(g² − 1) with a² + 2b² = 1 over an AR(1) g with ρ_g: moments in closed form
    (E z³ = 6a²b + 8b³, corr = a²ρ_g + 2b²ρ_g²), so the solve is checked exactly."""
    b, rho = gust_shape(np.array([skew]), np.array([corr]))
    a2 = 1 - 2 * b[0] ** 2
    assert 6 * a2 * b[0] + 8 * b[0] ** 3 == pytest.approx(skew, abs=1e-4)
    assert a2 * rho[0] + 2 * b[0] ** 2 * rho[0] ** 2 == pytest.approx(corr, abs=1e-9)


def test_a_gust_never_makes_an_action_free():
    """The quadratic term's floor (−a²/4b − b) times a large spread would go below zero; the
    cost stops at MIN_COST_SHARE of the mean."""
    mean, std = np.array([[1.0] * 5]), np.array([[2.0] * 5])
    b, g = np.array([0.5]), np.array([-0.707])  # z at its minimum, −0.75: 1 − 1.5 < 0
    cost = action_costs(np.array([0]), mean, std, b, g, True)
    assert cost[0] == pytest.approx(MIN_COST_SHARE)


def _downwind_costs(n: int, config: GridConfig, moves: int = 6) -> np.ndarray:
    mdp = GridMDP(COLUMN, n, config)
    mdp.reset(np.random.default_rng(1), budget=75)
    costs = []
    for _ in range(moves):
        before = mdp.budget.copy()
        mdp.step(np.full(n, SOUTH))
        costs.append(before - mdp.budget)
    return np.array(costs)


def test_the_gust_scale_widens_each_episodes_spread_by_its_own_factor():
    """gust_scale (2, 2) doubles the spread and keeps the mean; (1, 2) gives each episode its
    own factor, so the episodes' spreads differ — from the same winds and gust streams."""
    base = _downwind_costs(4000, steady())
    double = _downwind_costs(4000, steady(gust_scale=(2.0, 2.0)))
    assert double.std() == pytest.approx(2 * base.std(), rel=0.02)
    assert double.mean() == pytest.approx(base.mean(), rel=0.03)
    mixed = _downwind_costs(200, steady(gust_scale=(1.0, 2.0)), moves=40)
    spread = mixed.std(axis=0)  # per episode
    assert spread.max() > 1.6 * spread.min()
    np.testing.assert_array_equal(mixed, _downwind_costs(200, steady(gust_scale=(1.0, 2.0)), 40))
    with pytest.raises(ValueError, match="gust_scale"):
        GridWind(gust_scale=(1.0, float("nan")))
    with pytest.raises(ValueError, match="wind option"):
        TrainConfig(map="B", wind_gust_scale=1.5)  # no wind: the scale would do nothing


def test_calm_air_costs_the_calibrated_calm_move_with_no_spread():
    config = GridConfig(wind=GridWind(calm_fraction=1.0))
    env = gym.make("cpp_mujoco/Grid-v0", map=OPEN, config=config)
    obs, _ = env.reset(seed=5, options={"start": (2, 2), "budget": 10})
    assert not obs["wind"].any()
    env.step(NORTH)
    assert env.unwrapped.mdp.budget[0] == pytest.approx(10 - mean_cost("crosswind", 0.0))


def _budgets(env, seed, actions) -> tuple[list[float], list[float]]:
    """(observed wind, the exact budget after reset and after each action until the end)."""
    obs, _ = env.reset(seed=seed)
    budgets = [float(env.unwrapped.mdp.budget[0])]
    for a in actions:
        _, _, terminated, _, _ = env.step(a)
        budgets.append(float(env.unwrapped.mdp.budget[0]))
        if terminated:
            break
    return obs["wind"].tolist(), budgets


def test_the_same_seed_flies_the_same_winds_and_gusts_in_single_and_batched_envs():
    config = GridConfig(wind=GridWind())
    actions = [NORTH, EAST, EAST, SOUTH, WEST, NORTH, NORTH, EAST]
    single = gym.make("cpp_mujoco/Grid-v0", map="A", config=config)
    runs = [_budgets(single, s, actions) for s in (11, 12, 13)]
    assert runs[0] == _budgets(single, 11, actions)  # reproducible
    assert runs[0] != runs[1]  # and not the same episode for every seed
    vec = gym.make_vec(
        "cpp_mujoco/Grid-v0", num_envs=3, map="A", config=config, autoreset_mode="Disabled"
    )
    obs, _ = vec.reset(seed=[11, 12, 13])
    mdp = vec.unwrapped.mdp
    batched = [[float(b)] for b in mdp.budget]
    for a in actions:
        flying = ~mdp.done
        vec.step(np.full(3, a))
        for i in np.flatnonzero(flying):
            batched[i].append(float(mdp.budget[i]))
    for i, (wind, budgets) in enumerate(runs):
        assert obs["wind"][i].tolist() == wind
        assert batched[i] == budgets


def test_a_saved_wind_env_continues_exactly():
    config = GridConfig(wind=GridWind())
    a = gym.make_vec("cpp_mujoco/Grid-v0", num_envs=4, map="A", config=config)
    a.reset(seed=3)
    a.step(np.array([0, 1, 2, 3]))
    state = a.unwrapped.state_dict()
    assert {"wind_speed", "gust", "gust_key"} <= set(state)
    b = gym.make_vec("cpp_mujoco/Grid-v0", num_envs=4, map="A", config=config)
    b.reset(seed=99)
    b.unwrapped.load_state_dict(state)
    for act in ([1, 1, 1, 1], [2, 0, 2, 0]):
        oa, *_ = a.step(np.array(act))
        ob, *_ = b.step(np.array(act))
        np.testing.assert_array_equal(a.unwrapped.mdp.budget, b.unwrapped.mdp.budget)
        np.testing.assert_array_equal(oa["wind"], ob["wind"])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(max_speed=20.0), "calibrated range"),
        (dict(min_speed=5.0, max_speed=3.0), "min_speed <= max_speed"),
        (dict(calm_fraction=1.5), "calm_fraction"),
        (dict(max_speed=float("nan")), "finite"),
        (dict(directions=("NE",)), "directions"),
    ],
)
def test_bad_wind_options_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        GridWind(**kwargs)


def test_the_physics_env_refuses_the_grid_wind_option():
    with pytest.raises(ValueError, match="wind is flown"):
        gym.make("cpp_mujoco/MuJoCo-v0", map=OPEN, grid_config=GridConfig(wind=GridWind()))


def test_a_wind_network_started_from_a_calm_agent_acts_as_it_in_any_wind():
    torch.manual_seed(0)
    calm, windy = QNetwork(5, 5), QNetwork(5, 5, wind_inputs=True)
    windy.load_narrower(calm)
    env = gym.make("cpp_mujoco/Grid-v0", map=OPEN, config=steady())
    obs, _ = env.reset(seed=0)
    batch = {k: np.asarray(v)[None] for k, v in obs.items()}
    g, b = observation_to_tensors(batch, 1.0)
    gw, bw = observation_to_tensors(batch, 1.0, wind_inputs=True)
    assert bw.shape == (1, 4) and bw[0, 2] != 0 and bw[0, 3] > 0  # the wind reaches it …
    torch.testing.assert_close(calm(g, b), windy(gw, bw))  # … with zero weight at first


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--init-from", "Z"], "unknown agent 'Z'"),
        (["--init-from", "A-wind"], "without wind inputs from one with them"),
        (["--wind-max-speed", "12", "--set", "wind_calm_fraction=nan"], "not a number (NaN)"),
        (["--wind-max-speed", "30"], "calibrated range"),
    ],
)
def test_bad_wind_training_options_fail_before_the_run_folder_exists(
    tmp_path, capsys, options, message
):
    from cpp_mujoco.cli.main import main

    out = tmp_path / "run"
    code = main(["train", "--map", "A", "--out", str(out), "--total-updates", "1", *options])
    assert code == 2 and message in capsys.readouterr().err
    assert not out.exists()
