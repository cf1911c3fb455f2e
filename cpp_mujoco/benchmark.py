"""``cpp-mujoco benchmark``: the speed figures the README quotes, measured on this machine.

Each section returns a flat dict of numbers; the CLI prints them as a table and writes JSON.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.evaluate import evaluate
from cpp_mujoco.planners import BeamSearchPlanner, SafeGreedyPlanner


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

    envs = gym.make_vec("cpp_mujoco/Grid-v0", num_envs=num_envs, map=map_name)
    envs.reset(seed=0)
    batch_actions = rng.integers(5, size=(64, num_envs))

    def batch_step() -> int:
        for a in batch_actions:
            envs.step(a)
        return 64 * num_envs

    result = {
        "single_env_steps_per_s": _timed_loop(single_step, seconds),
        f"batched_env_steps_per_s_{num_envs}_envs": _timed_loop(batch_step, seconds),
    }
    for planner in (SafeGreedyPlanner(), BeamSearchPlanner()):
        start = time.perf_counter()
        outcome = evaluate(planner, map_name)
        key = planner.name.replace("-", "_")
        result[f"protocol_{key}_s"] = time.perf_counter() - start
        result[f"protocol_{key}_episodes"] = int(outcome.landed.size)
    return result


def benchmark_physics() -> dict:
    from cpp_mujoco.physics.benchmark import benchmark_physics as run

    return run(seconds=5.0)


def benchmark_training() -> dict:
    from cpp_mujoco.agent.benchmark import benchmark_training as run

    return run(updates=100)


def benchmark_review() -> dict:
    from cpp_mujoco.review.benchmark import benchmark_review as run
    from cpp_mujoco.review.rendering import configure_gl

    configure_gl()
    return run()


SECTIONS: dict[str, Callable[[], dict]] = {
    "grid": benchmark_grid,
    "physics": benchmark_physics,
    "training": benchmark_training,
    "review": benchmark_review,
}
