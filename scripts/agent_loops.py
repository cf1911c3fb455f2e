"""How often a greedy policy oscillates: the share of protocol episodes on a map set in which it
flies a two-cell cycle (or hovers) for at least ``--min-steps`` steps in a row.

    python scripts/agent_loops.py --map-set heldout16-v1 --agent general [--min-steps 10]

Why: a deterministic greedy policy in a state that differs from an earlier one only by the
budget repeats itself, and a cycle never sees a new cell after its first pass — the general
agent's largest coverage losses on unseen maps are such cycles near its start (docs/agent.md,
"Known limits"). A fix (an input of the cells visited, a recurrent network) is measured by this
number going down. Grid backend, every landing cell × every budget of the size class.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from cpp_mujoco.agent import load_agent
from cpp_mujoco.map_sets.sets import load_map_set, map_set_spec
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.protocol.evaluate import evaluate


def longest_cycle_run(trajectory: np.ndarray) -> int:
    """Steps of the longest run in which every cell equals the one two steps before (a hover
    or a back-and-forth between two cells); ``trajectory`` is flat cells, −1 after the end."""
    cells = trajectory[trajectory >= 0]
    same = np.concatenate([[False], cells[2:] == cells[:-2], [False]])
    if not same.any():
        return 0
    edges = np.flatnonzero(np.diff(same.astype(np.int8)))  # run starts and ends, in pairs
    return int((edges[1::2] - edges[::2]).max())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--map-set", default="heldout16-v1")
    p.add_argument("--agent", default="general", help="a bundled agent's name or a file")
    p.add_argument("--min-steps", type=int, default=10)
    p.add_argument("--first", type=int, default=None, help="only the set's first maps")
    args = p.parse_args(argv)
    agent, spec = load_agent(args.agent), map_set_spec(args.map_set)
    config = size_config(spec.size)
    rows = []
    for grid_map in load_map_set(args.map_set, args.first):
        result = evaluate(agent, grid_map, config=config)
        runs = np.array([longest_cycle_run(t) for t in result.trajectories])
        rows.append(
            {"map": grid_map.label, "episodes": int(runs.size),
             "cycling": int((runs >= args.min_steps).sum()),
             "coverage_ratio": result.coverage_ratio}
        )  # fmt: skip
    episodes = sum(r["episodes"] for r in rows)
    cycling = sum(r["cycling"] for r in rows)
    print(json.dumps({
        "map_set": spec.identity(len(rows)), "policy": agent.name,
        "digest": agent.metadata.get("digest"), "min_steps": args.min_steps,
        "episodes": episodes, "cycling_episodes": cycling, "share": cycling / episodes,
        "worst_maps": sorted(rows, key=lambda r: -r["cycling"])[:5],
    }, indent=2))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
