"""The return guard: its energy bookkeeping, its way home, and that it brings the UAV back."""

import gymnasium as gym
import pytest

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.agent import load_agent
from cpp_mujoco.grid.actions import EAST, LAND, NORTH, SOUTH, WEST
from cpp_mujoco.grid.wind import KIND_INDEX, wind_costs
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.return_guard import GuardSettings, ReturnGuard
from cpp_mujoco.protocol.evaluate import evaluate

STRIP = GridMap.from_ascii(["LTTTTTTT", "TTTTTTTT"], name="strip")
UNIT = 500.0
DRAG = 0.5 * 1.225 * 0.08  # ½ρC_dA of the airframe
TABLE = wind_costs()


def table_cost(kind: str, speed: float) -> tuple[float, float]:
    row = list(TABLE.speeds).index(speed)
    return TABLE.mean[row, KIND_INDEX[kind]] * UNIT, TABLE.std[row, KIND_INDEX[kind]] * UNIT


def test_the_prior_is_the_flown_cost_of_each_kind_at_the_wind_felt():
    guard = ReturnGuard(STRIP, UNIT, DRAG)
    calm_move = table_cost("crosswind", 0.0)[0]
    assert guard.prior(WEST)[0] == pytest.approx(calm_move)  # nothing felt: calm air
    # a 9 m/s wind from the west pushes east with ½ρC_dA·81 N: west is upwind, north across
    guard.observe(EAST, False, 460.0, external_force=(DRAG * 81.0, 0.0))
    speed, upwind = guard.wind_estimate()
    assert speed == pytest.approx(9.0) and upwind == pytest.approx((-1.0, 0.0))
    for heading, kind in ((WEST, "upwind"), (NORTH, "crosswind"), (EAST, "downwind")):
        mean, std, rho = guard.prior(heading)
        assert (mean, std) == pytest.approx(table_cost(kind, 9.0)), kind
        assert rho == pytest.approx(TABLE.correlation[list(TABLE.speeds).index(9.0)])
    assert guard.prior(LAND)[0] == pytest.approx(table_cost("hover", 9.0)[0])


def test_a_headings_estimate_pools_the_flight_with_the_prior():
    settings = GuardSettings(sigmas=2.0, prior_weight=3.0)
    guard = ReturnGuard(STRIP, UNIT, DRAG, settings)
    prior_mean, prior_std, _ = guard.prior(EAST)
    flown = [450.0, 470.0, 460.0, 520.0, 530.0]
    for joules in flown:
        guard.observe(EAST, False, joules)
    mean = (sum(flown) + 3 * prior_mean) / 8
    var = (sum((x - mean) ** 2 for x in flown) + 3 * (prior_std**2 + (prior_mean - mean) ** 2)) / 8
    assert guard.stats(EAST) == pytest.approx((mean, var))
    assert guard.cost(EAST) == pytest.approx(mean + 2 * var**0.5)
    guard.observe(WEST, True, 480.0)  # a rejected action is a hover, not a westward move
    assert len(guard.samples[LAND]) == 1 and not guard.samples[WEST]
    guard.observe(LAND, False, 999.0)  # a landing ends the episode: nothing to learn
    assert len(guard.samples[LAND]) == 1


def test_the_way_home_is_the_cheapest_in_expected_energy_with_its_variance_summed():
    # from the east end of the lower row: west along the row (7 moves) then north, or north first
    guard = ReturnGuard(STRIP, UNIT, DRAG)
    for h in (NORTH, SOUTH, WEST, EAST):
        for _ in range(5):
            guard.observe(h, False, 400.0)
    dist, variance, following = guard.way_home()
    start = 1 * 8 + 7
    mean, var = guard.stats(WEST)
    assert dist[start] == pytest.approx(8 * mean) and variance[start] == pytest.approx(8 * var)
    assert dist[0] == 0.0 and variance[0] == 0.0
    cell, path = start, []
    while cell != 0:
        cell = following[cell]
        path.append(cell)
    assert len(path) == 8 and path[-1] == 0


def test_it_lets_the_policy_fly_while_the_way_home_is_paid_then_takes_over_for_good():
    settings = GuardSettings(sigmas=3.0, reserve_units=0.25)
    guard = ReturnGuard(STRIP, UNIT, DRAG, settings)
    for h in (NORTH, EAST, SOUTH, WEST):
        guard.observe(h, False, UNIT)
    # at (0, 3): home is 3 moves; flying on east leaves 4 moves home + a unit + the reserve
    mean, var = guard.stats(EAST)
    rho = guard.prior(LAND)[2]
    gust = guard.gust_factor()  # these moves cost a little more than the calm calibration
    assert gust == pytest.approx(UNIT / guard.prior(EAST)[0], rel=0.01) and gust > 1.0
    needed = 5 * mean * gust + 3 * (5 * var * (1 + rho) / (1 - rho)) ** 0.5 + UNIT * 1.25
    assert guard.filter(3, EAST, needed + 1.0) == EAST and not guard.active
    assert guard.filter(3, EAST, needed - 1.0) == WEST and guard.active and guard.homing
    assert guard.filter(2, WEST, needed - 1.0) == WEST and not guard.active  # homeward anyway
    assert guard.filter(2, EAST, 1e9) == WEST and guard.active  # homing: no turning away
    assert guard.filter(2, NORTH, 0.0) == WEST and guard.active  # rejected: would hover
    assert guard.filter(0, EAST, 10.0) == LAND and guard.takeovers == 4
    assert guard.filter(0, LAND, 0.0) == LAND and not guard.active
    guard.reset()
    assert guard.takeovers == 0 and not guard.homing and guard.filter(3, EAST, 1e9) == EAST


def test_dear_recent_actions_make_the_way_home_dearer():
    """A gust lasts several actions: after moves that cost twice their calibrated cost the
    guard prices the way home twice as dear and turns back where it would have flown on."""
    calm, gusty = ReturnGuard(STRIP, UNIT, DRAG), ReturnGuard(STRIP, UNIT, DRAG)
    for guard, factor in ((calm, 1.0), (gusty, 2.0)):
        for _ in range(6):  # the running ratio forgets the start: (1 - w)^6 of it is left
            guard.observe(NORTH, False, factor * guard.prior(NORTH)[0])
            guard.observe(SOUTH, False, factor * guard.prior(SOUTH)[0])
    assert calm.gust_factor() == pytest.approx(1.0)
    assert gusty.gust_factor() == pytest.approx(2.0, rel=0.02)
    remaining = 6.0 * UNIT  # at (0, 2), two moves home: enough for calm air, not for the gust
    assert calm.filter(2, EAST, remaining) == EAST and not calm.active
    assert gusty.filter(2, EAST, remaining) == WEST and gusty.active
    cheap = ReturnGuard(STRIP, UNIT, DRAG)
    cheap.observe(NORTH, False, 0.5 * cheap.prior(NORTH)[0])
    assert cheap.gust_factor() == 1.0  # cheaper than expected never shrinks the way home


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
    # the policy flew first; then the guard overruled most of its eastward steps until it
    # landed (some pass where moves home came cheaper than the guard had feared)
    assert 0 < turn and active[-1] and sum(active[turn:]) > len(active[turn:]) / 2
    assert guarded["nfz_violations"] == 0


def test_in_calm_air_the_guard_costs_the_bundled_agent_almost_nothing():
    agent = load_agent("B")
    runs = {
        guard: evaluate(
            agent,
            "B",
            backend="mujoco",
            budgets=[30, 45],
            workers=1,  # in this process, all episodes in one batch: no workers to spawn
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
