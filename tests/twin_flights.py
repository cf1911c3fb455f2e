"""Two batched physics envs that must fly the same doubles: the same seeds, budgets and actions,
then every observation, reward, flag, info and each drone's whole MuJoCo state row compared
after every step."""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.actions import EAST, LAND, NORTH, SOUTH, WEST
from cpp_mujoco.maps import GridMap

# an open 5×6 map: landing strip in the middle row, targets around, one no-fly cell
MAP = GridMap.from_ascii(["TTTTTT", "T..N.T", "TLLLLT", "T....T", "TTTTTT"], name="open")
WIND = {"wind_speed": 9.0, "wind_direction": 270.0, "turbulence": "moderate"}


def fly_twins(envs, budgets, actions_of, steps: int = 30, perturb=None) -> list:
    """Fly ``envs`` (two vector envs of ``len(budgets)`` drones) side by side and assert that
    they agree to the last bit. ``perturb(state, cols)`` edits both envs' state rows after the
    reset. Returns each episode's ending (crash reason, "landed", or None: still flying)."""
    n = len(budgets)
    for env in envs:
        env.reset(seed=[100 + i for i in range(n)], options={"budget": np.array(budgets)})
        if perturb is not None:
            perturb(env.flight.state, env.flight.cols)
    ended: list = [None] * n
    for step in range(steps):
        actions = actions_of(step, n)
        (obs, rew, term, trunc, info), (o2, r2, t2, tr2, i2) = (e.step(actions) for e in envs)
        where = f"step {step}"
        for key in obs:
            np.testing.assert_array_equal(obs[key], o2[key], err_msg=f"{where}: {key}")
        for a, b in ((rew, r2), (term, t2), (trunc, tr2)):
            np.testing.assert_array_equal(a, b, err_msg=where)
        for key in info:
            np.testing.assert_array_equal(info[key], i2[key], err_msg=f"{where}: {key}")
        np.testing.assert_array_equal(envs[0].flight.state, envs[1].flight.state, err_msg=where)
        for i in np.flatnonzero(term & np.equal(ended, None)).tolist():
            ended[i] = "landed" if info["landed"][i] else info["crash_reason"][i]
        if all(e is not None for e in ended):
            break
    for env in envs:
        env.close()
    return ended


def wander(seed: int, land: float):
    """Random moves (hovers where the map rejects one), a landing with probability ``land``."""
    rng = np.random.default_rng(seed)
    return lambda step, n: np.where(rng.random(n) < land, LAND, rng.integers(0, 4, size=n))


# the failure scenario both twin tests fly: drone 0 diverges, drone 1 is so fast that the pack
# cannot carry its load (motors cut, a fall), drone 2 starts upside down; the rest fly on
FAILURE_MOVES = [NORTH, SOUTH, EAST, WEST] * 4


def break_three(state, cols) -> None:
    """``perturb`` for :func:`fly_twins`: the three broken drones of the failure scenario."""
    q, v = cols[0], cols[1]
    state[0, v.start] = 1e6
    state[1, v.start] = 1e12
    state[2, q.start + 3 : q.start + 7] = (0.0, 1.0, 0.0, 0.0)


def failure_moves(step: int, n: int):
    return np.full(n, FAILURE_MOVES[step])
