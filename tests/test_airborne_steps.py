"""Drones clear of the ground step on a model without contacts: the same doubles, cheaper."""

from __future__ import annotations

import numpy as np
import pytest

from cpp_mujoco.physics.airborne import air_model, ground_top, reach_below
from cpp_mujoco.physics.envs.vector import MuJoCoVectorEnv
from tests.twin_flights import (
    FAILURE_MOVES,
    MAP,
    WIND,
    break_three,
    failure_moves,
    fly_twins,
    wander,
)


def _twins(n: int, **kwargs) -> list[MuJoCoVectorEnv]:
    """Two batched envs, the first stepping airborne drones without contacts, the second
    stepping every drone on the full model; both record which model each step used."""
    envs = [MuJoCoVectorEnv(n, MAP, **kwargs) for _ in range(2)]
    envs[1].flight.air = None
    air = envs[0].flight.air
    air.seen = {"air": 0, "ground": 0}
    before = air.before_step

    def counting(drones, nstep):
        before(drones, nstep)
        on_air = np.count_nonzero(air.airborne[drones])
        air.seen["air"] += on_air
        air.seen["ground"] += len(drones) - on_air

    air.before_step = counting
    return envs


def test_the_quadrotor_reaches_its_skid_tips_and_the_ground_is_the_plane():
    env = MuJoCoVectorEnv(1, MAP)
    model, flight = env.model, env.flight
    frame = int(model.body_parentid[flight.params.body_id])
    # the skids: capsules of radius 8 mm, 0.2 m long, centred (0, ±0.11, −0.17) from the origin;
    # their bounding spheres reach past the tips, which are what can touch
    reach = reach_below(model, frame)
    assert reach == pytest.approx(np.hypot(0.11, 0.17) + 0.1 + 0.008)
    assert reach > np.hypot(np.hypot(0.1, 0.11), 0.17) + 0.008
    assert ground_top(model) == 0.0
    air = air_model(model)
    assert air.opt.disableflags != model.opt.disableflags
    assert model.opt.disableflags == 0  # the env's own model keeps its contacts


def test_who_counts_as_clear_of_the_ground():
    env = MuJoCoVectorEnv(4, MAP)
    env.reset(seed=0)
    air, st = env.flight.air, env.flight.state
    q, v = env.flight.cols[0].start, env.flight.cols[1].start
    st[:, q + 2] = (6.0, 0.3, 1.1, np.nan)  # cruise, skids near the ground, 1.1 m up, broken
    st[:, v + 2] = (0.0, 0.0, -40.0, 0.0)  # the third sinks at 40 m/s: 0.8 m in a tick
    assert air.clear(np.arange(4), 5).tolist() == [True, False, False, False]
    assert air.clear(np.array([2]), 1).tolist() == [True]  # one substep: 0.16 m
    st[0, v] = 60.0  # at cruise, but faster than any flight: the full model's numerics
    assert air.clear(np.arange(1), 5).tolist() == [False]


@pytest.mark.parametrize("kwargs", [{}, WIND], ids=["calm", "wind-9-moderate"])
def test_airborne_steps_fly_the_full_models_doubles(kwargs):
    """Moves, hovers, landings and emergency landings: every drone's state row is the same after
    every step, and both models were used (air at cruise, ground near touchdown)."""
    envs = _twins(6, **kwargs)
    with np.errstate(all="ignore"):
        ended = fly_twins(envs, [3, 5, 8, 12, 4, 20], wander(7, 0.15))
    assert "landed" in ended
    seen = envs[0].flight.air.seen
    assert seen["air"] > 0 and seen["ground"] > 0


def test_failures_near_and_into_the_ground_end_alike():
    """A diverging drone, a motor cut-off (the pack cannot carry the load: a fall onto the
    ground), one upside down, then cut-off landings: the same ends to the last bit."""
    with np.errstate(all="ignore"):
        ended = fly_twins(_twins(5, battery_cutoff_v=3.95), [10] * 5, failure_moves,
                          steps=len(FAILURE_MOVES), perturb=break_three)  # fmt: skip
    assert ended[0] == "numerical divergence (NaN or unstable acceleration)"
    assert ended[1].startswith("battery")
    assert ended[2] == "flipped over"
