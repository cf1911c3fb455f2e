"""Peak memory of the grid backend and the planners on a large random map.

Builds a random-but-valid side×side map (a landing block, scattered targets, some no-fly), then
steps ``Grid-v0``, a 64-env ``GridMDP`` batch, and the safe greedy and beam search planners
through ``evaluate`` (every landing cell × the given budgets), and prints one JSON line with the
peak resident set size. Run one size per process: the peak is per process.

    .venv/bin/python scripts/peak_memory.py --side 128
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time

import numpy as np


def random_map(side: int, seed: int = 0, landing: tuple[int, int] = (1, 2)):
    """A valid map: a landing block near the middle, ~10 % targets, ~8 % no-fly (never on it)."""
    from cpp_mujoco.maps import GridMap

    rng = np.random.default_rng(seed)
    land = np.zeros((side, side), dtype=bool)
    r0, c0 = side // 2, side // 2
    land[r0 : r0 + landing[0], c0 : c0 + landing[1]] = True
    nfz = (rng.random((side, side)) < 0.08) & ~land
    target = rng.random((side, side)) < 0.10
    return GridMap(landing=land, target=target, nfz=nfz, name=f"random{side}")


def run(side: int, budgets: list[int], steps: int = 200) -> dict:
    import gymnasium as gym

    import cpp_mujoco  # noqa: F401  (registers the envs)
    from cpp_mujoco.grid.mdp import GridMDP
    from cpp_mujoco.planners import BeamSearchPlanner, SafeGreedyPlanner
    from cpp_mujoco.protocol.evaluate import evaluate

    start = time.perf_counter()
    grid_map = random_map(side)
    rng = np.random.default_rng(0)
    env = gym.make("cpp_mujoco/Grid-v0", map=grid_map)
    env.reset(seed=0)
    for a in rng.integers(5, size=steps):
        if env.step(int(a))[2]:
            env.reset()
    mdp = GridMDP(grid_map, 64)
    mdp.reset(rng)
    for _ in range(steps):
        mdp.step(rng.integers(5, size=64))
        mdp.observation()
    result = {"side": side, "budgets": budgets}
    for planner in (SafeGreedyPlanner(), BeamSearchPlanner()):
        outcome = evaluate(planner, grid_map, budgets=budgets)
        result[f"{planner.name}_coverage"] = [round(float(c), 4) for c in outcome.coverage]
        result[f"{planner.name}_landed"] = bool(outcome.landed.all())
    result["seconds"] = round(time.perf_counter() - start, 2)
    scale = 1 if sys.platform == "darwin" else 1024  # ru_maxrss: bytes on macOS, KiB on Linux
    result["peak_rss_mib"] = round(
        resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * scale / 2**20, 1
    )
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", type=int, default=128, help="map side in cells (default 128)")
    parser.add_argument("--budgets", type=int, nargs="+", default=[40, 75])
    args = parser.parse_args()
    print(json.dumps(run(args.side, args.budgets)))


if __name__ == "__main__":
    main()
