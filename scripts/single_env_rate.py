"""Actions/s of one ``MuJoCo-v0`` env: random moves with 2 % landings on map A, budget 75, a new
episode whenever one ends (the workload of ``python -m cpp_mujoco.bench.physics``).

It uses only the env's public API, so it measures any checkout of the package: to compare two,
alternate them on one core, e.g.::

    for r in 1 2 3 4 5 6; do
      PYTHONPATH=/path/to/other/checkout taskset -c 1 python scripts/single_env_rate.py 6
      taskset -c 1 python scripts/single_env_rate.py 6
    done
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import cpp_mujoco


def rate(seconds: float, map_name: str = "A", seed: int = 0) -> float:
    """Grid actions per wall-clock second over ``seconds``, after 20 warm-up actions."""
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=map_name).unwrapped  # the env, no wrappers
    rng = np.random.default_rng(seed)

    def action() -> int:
        return int(4 if rng.random() < 0.02 else rng.integers(0, 4))

    env.reset(seed=seed, options={"budget": 75})
    for _ in range(20):  # compiled kernels loaded from numba's cache, caches warm
        *_, terminated, _, _ = env.step(action())
        if terminated:
            env.reset(options={"budget": 75})
    actions, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        *_, terminated, _, _ = env.step(action())
        actions += 1
        if terminated:
            env.reset(options={"budget": 75})
    return actions / (time.perf_counter() - start)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("seconds", nargs="?", type=float, default=6.0)
    parser.add_argument("--map", default="A")
    args = parser.parse_args(argv)
    print(f"{cpp_mujoco.__file__}: {rate(args.seconds, args.map):.1f} actions/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
