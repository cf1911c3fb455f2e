"""Speed of the grid MDP: single and batched env-steps/s, and full-protocol wall times of the
reference planners (the ``grid`` section of ``cpp-mujoco benchmark``)."""

from __future__ import annotations

import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.grid.wind import GridWind
from cpp_mujoco.planners import BeamSearchPlanner, SafeGreedyPlanner
from cpp_mujoco.protocol.evaluate import evaluate


def _timed_loop(step: Callable[[], int], seconds: float) -> float:
    """Call ``step`` (which returns how many env-steps it did) for ``seconds``; steps per second."""
    done, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        done += step()
    return done / elapsed


def benchmark_grid(map_name: str = "A", seconds: float = 3.0, num_envs: int = 1024) -> dict:
    """Single-env and batched env-steps/s with random actions, and full-protocol wall times."""
    rng = np.random.default_rng(0)
    env = gym.make("cpp_mujoco/Grid-v0", map=map_name)
    env.reset(seed=0)
    actions = rng.integers(5, size=1 << 16).tolist()
    cursor = 0

    def single_step() -> int:
        nonlocal cursor
        for _ in range(1000):
            _, _, terminated, _, _ = env.step(actions[cursor])
            cursor = (cursor + 1) & 0xFFFF
            if terminated:
                env.reset()
        return 1000

    batch_actions = rng.integers(5, size=(64, num_envs))

    def batch_stepper(config: GridConfig) -> Callable[[], int]:
        envs = gym.make_vec("cpp_mujoco/Grid-v0", num_envs=num_envs, map=map_name, config=config)
        envs.reset(seed=0)

        def batch_step() -> int:
            for a in batch_actions:
                envs.step(a)
            return 64 * num_envs

        return batch_step

    result = {
        "single_env_steps_per_s": _timed_loop(single_step, seconds),
        f"batched_env_steps_per_s_{num_envs}_envs": _timed_loop(
            batch_stepper(GridConfig()), seconds
        ),
        # the power-variation option: per-action costs from the wind, gusts hashed per step
        f"batched_wind_env_steps_per_s_{num_envs}_envs": _timed_loop(
            batch_stepper(GridConfig(wind=GridWind())), seconds
        ),
    }
    for planner in (SafeGreedyPlanner(), BeamSearchPlanner()):
        start = time.perf_counter()
        outcome = evaluate(planner, map_name)
        key = planner.name.replace("-", "_")
        result[f"protocol_{key}_s"] = time.perf_counter() - start
        result[f"protocol_{key}_episodes"] = int(outcome.landed.size)
    return result


def run() -> dict:
    """The ``grid`` section as ``cpp-mujoco benchmark`` runs it."""
    return benchmark_grid()
