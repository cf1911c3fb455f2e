"""The compiled control tick (numba) flies the numpy tick's doubles."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from cpp_mujoco.physics import compiled_tick
from cpp_mujoco.physics.battery import CUTOFF
from cpp_mujoco.physics.vector_env import MuJoCoVectorEnv
from tests.twin_flights import (
    FAILURE_MOVES,
    MAP,
    WIND,
    break_three,
    failure_moves,
    fly_twins,
    wander,
)


def _fly_both(kwargs: dict, budgets, actions_of, steps: int = 30, perturb=None) -> list:
    """The same episodes through a compiled and a numpy batched env (:func:`fly_twins`)."""
    pytest.importorskip("numba")
    envs = [MuJoCoVectorEnv(len(budgets), MAP, tick=t, **kwargs) for t in ("compiled", "numpy")]
    assert [e.flight.tick for e in envs] == ["compiled", "numpy"]
    return fly_twins(envs, budgets, actions_of, steps, perturb)


@pytest.mark.parametrize(
    "kwargs",
    [{}, WIND, {**WIND, "gust_std": 1.0, "power_model": "momentum", "return_guard": True}],
    ids=["calm", "wind-9-moderate", "gusts-momentum-guard"],
)
def test_compiled_and_numpy_ticks_fly_the_same_episodes(kwargs):
    """Moves, hovers and landings in calm air and in 9 m/s moderate turbulence (forward-flight
    power, per-drone gusts), small budgets running out (emergency landings): the same cells,
    budgets, energies, positions and failures to the last bit."""
    with np.errstate(all="ignore"):
        ended = _fly_both(kwargs, [3, 5, 8, 12, 4, 20], wander(7, 0.1))
    assert "landed" in ended


def test_failures_and_the_battery_failsafe_end_alike():
    """A diverging drone, one so fast that the pack cannot carry its load (motors cut, a fall),
    one upside down, then a cut-off landing (the failsafe) for the rest."""
    with np.errstate(all="ignore"):
        ended = _fly_both({"battery_cutoff_v": 3.95}, [10] * 5, failure_moves,
                          steps=len(FAILURE_MOVES), perturb=break_three)  # fmt: skip
    assert ended[0] == "numerical divergence (NaN or unstable acceleration)"
    assert ended[1].startswith("battery")
    assert ended[2] == "flipped over"
    assert ended[3:] == [CUTOFF, CUTOFF]


def test_an_airspeed_off_the_turbulence_table_flies_the_numpy_control(monkeypatch):
    """A tick with a turbulence time scale the compiled tick has no row for (here: none fits)
    flies the numpy twin's control on the same state arrays: still the same doubles."""
    monkeypatch.setattr(compiled_tick, "_MAX_KEYS", 0)
    _fly_both(WIND, [5, 8, 12], wander(3, 0.2), steps=5)


def test_the_tick_switch(monkeypatch):
    """``tick``: "auto" flies compiled where numba imports and numpy where it does not;
    "compiled" without numba names the extra to install; CPP_MUJOCO_TICK is the default."""
    with pytest.raises(ValueError, match="tick must be one of"):
        MuJoCoVectorEnv(1, MAP, tick="fast")
    monkeypatch.setenv("CPP_MUJOCO_TICK", "numpy")
    assert MuJoCoVectorEnv(1, MAP).flight.tick == "numpy"
    monkeypatch.delenv("CPP_MUJOCO_TICK")
    monkeypatch.setitem(sys.modules, "numba", None)  # as if numba were not installed
    assert MuJoCoVectorEnv(1, MAP).flight.tick == "numpy"
    with pytest.raises(ImportError, match="a dependency of cpp_mujoco"):
        MuJoCoVectorEnv(1, MAP, tick="compiled")
