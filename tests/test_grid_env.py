"""The paper's grid MDP rules, cell by cell, through the public gymnasium env."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.grid.actions import EAST, LAND, NORTH, SOUTH, WEST
from cpp_mujoco.maps import GridMap

R_COV, R_MOV, R_SC, R_CRASH = 0.4, -0.2, -1.0, -150.0

# 5×5: landing in the south-west corner, a no-fly cell at (2,2), targets in the east.
SMALL = GridMap.from_ascii(
    [
        "...TT",
        "...TT",
        "..N..",
        "LL...",
        "LL...",
    ],
    name="small",
)


def make(grid_map=SMALL, **kwargs):
    return gym.make("cpp_mujoco/Grid-v0", map=grid_map, **kwargs)


def test_check_env_passes_for_bundled_maps():
    for name in "ABC":
        check_env(gym.make("cpp_mujoco/Grid-v0", map=name, render_mode="rgb_array").unwrapped)


def test_reset_observation_and_info():
    env = make()
    obs, info = env.reset(seed=0, options={"start": (4, 0), "budget": 30})
    assert set(obs) == {"map", "coverage", "position", "budget", "safety", "wind"}
    np.testing.assert_array_equal(obs["wind"], [0.0, 0.0])  # the paper's MDP is calm
    np.testing.assert_array_equal(obs["map"][0], SMALL.landing)
    np.testing.assert_array_equal(obs["map"][1], SMALL.target)
    np.testing.assert_array_equal(obs["map"][2], SMALL.nfz)
    assert obs["coverage"].sum() == 0
    assert obs["position"].sum() == 1 and obs["position"][4, 0] == 1
    assert obs["budget"][0] == 30 and obs["safety"][0] == 0
    assert info == {
        "position": (4, 0),
        "budget": 30,
        "landed": False,
        "crashed": False,
        "rejected": False,
        "coverage_ratio": 0.0,
    }


def test_random_reset_draws_landing_cells_and_budgets_in_range():
    env = make()
    starts, budgets = set(), set()
    for seed in range(200):
        _, info = env.reset(seed=seed)
        starts.add(info["position"])
        budgets.add(info["budget"])
    assert starts == {(3, 0), (3, 1), (4, 0), (4, 1)}
    assert min(budgets) >= 25 and max(budgets) <= 75 and len(budgets) > 30


def test_bad_reset_options_are_clear_errors():
    env = make()
    with pytest.raises(ValueError, match=r"\(0, 0\) is not a landing cell"):
        env.reset(options={"start": (0, 0)})
    with pytest.raises(ValueError, match="outside"):
        env.reset(options={"start": (9, 0)})
    with pytest.raises(ValueError, match="budget"):
        env.reset(options={"budget": 0})
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"fuel": 3})


def _assert_rejected_hover(env, action, where, budget_before):
    obs, reward, terminated, truncated, info = env.step(action)
    assert info["rejected"] and info["position"] == where
    assert info["budget"] == budget_before - 1  # a rejected action still costs one unit
    assert obs["safety"][0] == 1
    assert not terminated and not truncated
    return reward


def test_moves_off_every_edge_are_rejected():
    env = make()
    env.reset(options={"start": (4, 0), "budget": 30})
    assert _assert_rejected_hover(env, SOUTH, (4, 0), 30) == pytest.approx(R_MOV + R_SC)
    assert _assert_rejected_hover(env, WEST, (4, 0), 29) == pytest.approx(R_MOV + R_SC)
    for _ in range(4):
        env.step(NORTH)
    _assert_rejected_hover(env, NORTH, (0, 0), 24)
    for _ in range(4):
        env.step(EAST)
    _assert_rejected_hover(env, EAST, (0, 4), 19)


def test_no_fly_cell_rejection_leaves_uav_in_place():
    env = make()
    env.reset(options={"start": (3, 1), "budget": 10})
    env.step(EAST)  # (3,2)
    _, _, _, _, info = env.step(NORTH)  # (2,2) is no-fly
    assert info["rejected"] and info["position"] == (3, 2)
    _, _, _, _, info = env.step(EAST)
    assert not info["rejected"] and info["position"] == (3, 3)


def test_safety_flag_resets_after_an_accepted_action():
    env = make()
    env.reset(options={"start": (4, 0), "budget": 10})
    obs, *_ = env.step(SOUTH)
    assert obs["safety"][0] == 1
    obs, *_ = env.step(NORTH)
    assert obs["safety"][0] == 0


def test_land_only_on_landing_cells():
    env = make()
    env.reset(options={"start": (3, 1), "budget": 10})
    env.step(EAST)  # (3,2) is not a landing cell
    _, reward, terminated, _, info = env.step(LAND)
    assert info["rejected"] and not info["landed"] and not terminated
    assert reward == pytest.approx(R_MOV + R_SC)
    env.step(WEST)
    _, reward, terminated, _, info = env.step(LAND)
    assert info["landed"] and terminated and not info["crashed"]
    assert reward == pytest.approx(R_MOV)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(NORTH)


def test_coverage_marked_after_every_step_including_the_landing_step():
    grid_map = GridMap.from_ascii(["T..", ".L.", "..T"])
    env = make(grid_map)
    obs, _ = env.reset(options={"start": (1, 1), "budget": 5})
    assert obs["coverage"].sum() == 0  # nothing is seen before the first step
    obs, reward, terminated, _, info = env.step(LAND)
    assert terminated and info["landed"]
    assert obs["coverage"].sum() == 9  # the whole 3×3 footprint
    assert reward == pytest.approx(2 * R_COV + R_MOV)
    assert info["coverage_ratio"] == 1.0


def test_fov_is_a_3x3_square_clipped_at_the_edges():
    env = make()
    env.reset(options={"start": (4, 0), "budget": 10})
    obs, *_ = env.step(NORTH)  # at (3,0)
    expected = np.zeros((5, 5), dtype=np.int8)
    expected[2:5, 0:2] = 1
    np.testing.assert_array_equal(obs["coverage"], expected)


def test_coverage_reward_counts_only_new_target_cells():
    env = make()
    env.reset(options={"start": (3, 1), "budget": 20})
    for a in (EAST, EAST):  # (3,3): FoV rows 2-4, cols 2-4 has no target
        _, reward, *_ = env.step(a)
        assert reward == pytest.approx(R_MOV)
    _, reward, *_ = env.step(NORTH)  # (2,3) sees (1,2..4): targets (1,3),(1,4)
    assert reward == pytest.approx(2 * R_COV + R_MOV)
    _, reward, *_ = env.step(NORTH)  # (1,3) sees rows 0-2: new targets (0,3),(0,4)
    assert reward == pytest.approx(2 * R_COV + R_MOV)
    _, reward, _, _, info = env.step(SOUTH)  # nothing new
    assert reward == pytest.approx(R_MOV) and info["coverage_ratio"] == 1.0


def test_crash_penalty_exactly_when_budget_hits_zero_unlanded():
    env = make()
    env.reset(options={"start": (4, 0), "budget": 2})
    _, reward, terminated, _, info = env.step(NORTH)
    assert not terminated and reward == pytest.approx(R_MOV)
    _, reward, terminated, truncated, info = env.step(NORTH)
    assert terminated and not truncated and info["crashed"] and info["budget"] == 0
    assert reward == pytest.approx(R_MOV + R_CRASH)


def test_landing_with_the_last_unit_is_not_a_crash():
    env = make()
    env.reset(options={"start": (4, 0), "budget": 1})
    _, reward, terminated, _, info = env.step(LAND)
    assert terminated and info["landed"] and not info["crashed"] and info["budget"] == 0
    assert reward == pytest.approx(R_MOV)


def test_rejected_last_action_crashes_with_both_penalties():
    env = make()
    env.reset(options={"start": (4, 0), "budget": 1})
    _, reward, terminated, _, info = env.step(SOUTH)
    assert terminated and info["crashed"] and info["rejected"]
    assert reward == pytest.approx(R_MOV + R_SC + R_CRASH)


def test_yellow_cells_are_covered_from_beside():
    grid_map = GridMap.from_ascii(["L.Y..", "L.Y.."])
    env = make(grid_map)
    env.reset(options={"start": (0, 0), "budget": 10})
    _, reward, _, _, info = env.step(EAST)  # (0,1) sees column 2: both yellow cells
    assert reward == pytest.approx(2 * R_COV + R_MOV) and info["coverage_ratio"] == 1.0
    _, _, _, _, info = env.step(EAST)  # the yellow cell itself is no-fly
    assert info["rejected"] and info["position"] == (0, 1)


def test_config_overrides_rewards_fov_and_budget_range():
    env = make(fov_side=1, rewards={"move": -0.5}, min_budget=3, max_budget=3)
    _, info = env.reset(seed=0)
    assert info["budget"] == 3
    obs, reward, *_ = env.step(NORTH)
    assert obs["coverage"].sum() == 1 and reward in (pytest.approx(-0.5), pytest.approx(-0.1))
    with pytest.raises(TypeError, match="unknown grid config"):
        make(fov=3)


def test_render_shows_the_map():
    env = make(render_mode="rgb_array")
    env.reset(options={"start": (4, 0), "budget": 5})
    frame = env.render()
    assert frame.shape == (5 * 16, 5 * 16, 3) and frame.dtype == np.uint8
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) >= 4  # zones, empty, UAV
