"""The compiled kernels fly what the same functions fly run as plain Python (``py_func``): the
readable reference of the one flight is its own source, not a hand-written twin."""

from __future__ import annotations

import contextlib

import numpy as np

from cpp_mujoco.physics import airborne
from cpp_mujoco.physics import tick_kernels as compiled_control
from cpp_mujoco.physics.envs.vector import MuJoCoVectorEnv
from cpp_mujoco.physics.power import kernels as compiled_power
from cpp_mujoco.physics.power.battery import CUTOFF
from cpp_mujoco.physics.sensing import camera
from cpp_mujoco.physics.sensing import kernels as compiled_sensing
from tests.twin_flights import (
    FAILURE_MOVES,
    MAP,
    WIND,
    break_three,
    failure_moves,
    fly_twins,
    wander,
)

# every kernel of a flight, by the module attribute the flight calls it through
KERNELS = [
    (compiled_control, "sense"),
    (compiled_control, "control"),
    (compiled_power, "power"),
    (camera, "frame"),
    (compiled_sensing, "_view"),  # the footprint, which frame calls through its module
    (airborne, "clear_of_ground"),
    (airborne, "changed"),
]


@contextlib.contextmanager
def as_python():
    """Every kernel of the flight runs uncompiled inside the block."""
    saved = [(module, name, getattr(module, name)) for module, name in KERNELS]
    try:
        for module, name, kernel in saved:
            setattr(module, name, kernel.py_func)
        yield
    finally:
        for module, name, kernel in saved:
            setattr(module, name, kernel)


class Uncompiled:
    """A vector env whose every reset and step runs the kernels as Python."""

    def __init__(self, env: MuJoCoVectorEnv):
        self.env, self.flight = env, env.flight

    def reset(self, **kwargs):
        with as_python():
            return self.env.reset(**kwargs)

    def step(self, actions):
        with as_python():
            return self.env.step(actions)

    def close(self) -> None:
        self.env.close()


def _fly_both(kwargs: dict, budgets, actions_of, steps: int = 12, perturb=None) -> list:
    envs = [MuJoCoVectorEnv(len(budgets), MAP, **kwargs) for _ in range(2)]
    return fly_twins([envs[0], Uncompiled(envs[1])], budgets, actions_of, steps, perturb)


def test_every_kernel_is_a_compiled_numba_function():
    for module, name in KERNELS:
        assert callable(getattr(module, name).py_func), f"{module.__name__}.{name}"


def test_compiled_and_python_kernels_fly_the_same_episodes():
    """Moves, hovers and landings in 9 m/s moderate turbulence with gusts, forward-flight power
    and the return guard, small budgets running out: the same doubles to the last bit."""
    kwargs = {**WIND, "gust_std": 1.0, "return_guard": True}
    with np.errstate(all="ignore"):
        ended = _fly_both(kwargs, [3, 5, 9, 4], wander(7, 0.15))
    assert any(e is not None for e in ended)


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
