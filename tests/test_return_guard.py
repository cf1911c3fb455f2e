"""The return guard: its energy bookkeeping, its way home, and that it brings the UAV back."""

import gymnasium as gym
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.agent import load_agent
from cpp_mujoco.evaluate import evaluate
from cpp_mujoco.grid.actions import EAST, LAND, NORTH, SOUTH, WEST
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.return_guard import GuardSettings, ReturnGuard

STRIP = GridMap.from_ascii(["LTTTTTTT", "TTTTTTTT"], name="strip")
UNIT = 500.0
DRAG = 0.5 * 1.225 * 0.08  # ½ρC_dA of the airframe
CAUTIOUS = GuardSettings(sigmas=2.0, min_spread=0.05, reserve_units=0.25)


def test_a_headings_cost_is_its_mean_plus_its_spread_and_unflown_headings_are_dearer():
    guard = ReturnGuard(STRIP, UNIT, DRAG, GuardSettings(sigmas=2.0, min_spread=0.05))
    assert guard.cost(WEST) == UNIT  # nothing flown yet: a calm unit
    for joules in (450.0, 470.0, 460.0):
        guard.observe(EAST, False, joules)
    std = np.std([450.0, 470.0, 460.0])
    assert guard.cost(EAST) == pytest.approx(460.0 + 2 * max(std, 25.0))
    assert guard.cost(WEST) == pytest.approx(guard.cost(EAST))  # no wind felt: alike
    guard.observe(WEST, True, 480.0)  # a rejected action is a hover, not a westward move
    assert guard.cost(LAND) == pytest.approx(480.0 + 2 * 25.0)
    assert guard.cost(WEST) == pytest.approx(guard.cost(EAST))
    # a 9 m/s wind from the west pushes east with ½ρC_dA·81 N: west is upwind, north across
    guard.observe(EAST, False, 460.0, external_force=(DRAG * 81.0, 0.0))
    assert guard.cost(WEST) == pytest.approx(1.25 * guard.cost(EAST))
    assert guard.cost(NORTH) == pytest.approx(guard.cost(EAST))
    guard.observe(LAND, False, 999.0)  # a landing ends the episode: nothing to learn
    assert guard.cost(LAND) == pytest.approx(530.0)


def test_the_way_home_is_the_cheapest_under_the_flown_costs_not_the_shortest():
    # from the east end of the lower row: west along the row (7 moves) then north, or north first
    guard = ReturnGuard(STRIP, UNIT, DRAG, CAUTIOUS)
    guard.observe(NORTH, False, 400.0), guard.observe(SOUTH, False, 400.0)
    guard.observe(WEST, False, 400.0), guard.observe(EAST, False, 400.0)
    dist, following = guard.way_home()
    start = 1 * 8 + 7
    assert dist[start] == pytest.approx(8 * (400.0 + 2 * 25.0))
    assert dist[0] == 0.0
    cell, path = start, []
    while cell != 0:
        cell = following[cell]
        path.append(cell)
    assert len(path) == 8 and path[-1] == 0


def test_it_lets_the_policy_fly_while_the_way_home_is_paid_then_takes_over_for_good():
    guard = ReturnGuard(STRIP, UNIT, DRAG, CAUTIOUS)
    for h in (NORTH, EAST, SOUTH, WEST):
        guard.observe(h, False, UNIT)
    per_move = UNIT + 2 * 25.0
    # at (0, 3): home is 3 moves; flying on east leaves 4 moves + a unit + the reserve to pay
    needed = per_move + 4 * per_move + UNIT * 1.25
    assert guard.filter(3, EAST, needed + 1.0) == EAST and not guard.active
    assert guard.filter(3, EAST, needed - 1.0) == WEST and guard.active
    assert guard.filter(2, WEST, needed - 1.0) == WEST and not guard.active  # homeward anyway
    assert guard.filter(2, NORTH, 0.0) == WEST and guard.active  # rejected: would hover
    assert guard.filter(0, EAST, 10.0) == LAND and guard.takeovers == 3
    assert guard.filter(0, LAND, 0.0) == LAND and not guard.active
    guard.reset()
    assert guard.takeovers == 0 and guard.filter(3, EAST, 1e9) == EAST


def test_the_option_is_a_bool():
    assert PhysicsConfig(return_guard=True).return_guard is True
    with pytest.raises(ValueError, match="return_guard must be True or False"):
        PhysicsConfig(return_guard="yes")


def fly_east(guard: bool) -> tuple[dict, list[bool]]:
    """Always east, downwind, away from the one landing cell; the way home is a 9 m/s headwind."""
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=STRIP, wind_speed=9.0, wind_direction=270.0,
                   return_guard=guard)  # fmt: skip
    _, info = env.reset(seed=0, options={"start": (0, 0), "budget": 16})
    active, done = [], False
    while not done:
        _, _, terminated, truncated, info = env.step(EAST)
        active.append(info["guard_active"])
        done = terminated or truncated
    return info, active


def test_in_a_headwind_home_the_guard_turns_in_time_and_lands():
    unguarded, active = fly_east(guard=False)
    assert unguarded["crashed"] and not any(active)
    guarded, active = fly_east(guard=True)
    assert guarded["landed"] and guarded["position"] == (0, 0)
    turn = active.index(True)
    # the policy flew first; then the guard overruled every eastward step until it landed
    assert 0 < turn and all(active[turn:])
    assert guarded["nfz_violations"] == 0


def test_in_calm_air_the_guard_costs_the_bundled_agent_almost_nothing():
    agent = load_agent("B")
    runs = {
        guard: evaluate(
            agent,
            "B",
            backend="mujoco",
            budgets=[30, 45],
            workers=2,
            env_kwargs={"return_guard": guard},
        )  # fmt: skip
        for guard in (False, True)
    }
    plain, guarded = runs[False], runs[True]
    assert guarded.landing_ratio >= plain.landing_ratio
    assert abs(guarded.coverage_ratio - plain.coverage_ratio) < 0.005
    takeovers = guarded.physics["guard_takeovers"]
    assert takeovers.sum() <= 0.05 * guarded.steps.sum()  # it intervenes rarely
    assert not plain.physics["guard_takeovers"].any()
