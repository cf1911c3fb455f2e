"""Where an agent's coverage falls behind the safe greedy planner's: mean coverage per budget over
validation-range maps, for the agent with and without the finish mask and for the planner.

    python scripts/budget_gap.py --agent general [--maps 32] [--first-seed 2000100]
    python scripts/budget_gap.py --agent general runs/X/best.pt --rules return-mask own
        # two agent files, each as its network alone (the return rule only) and with its rules

Why: a mean over every budget hides where a gap lies. On 32 validation-range 16×16 maps the
general agent led safe greedy at small budgets and fell behind at large ones, where it landed
with budget and reachable targets left — the finding behind the finish mask
(``cpp_mujoco/agent/rules/finish_mask.py``). Validation seeds only: the held-out sets stay the test.
Grid backend, every landing cell × every ``--budget-step``-th budget of the size class.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.map_pool import VALIDATION_SEEDS, MapPool, check_seeds
from cpp_mujoco.cli.maps import agent_entry
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets


def per_budget_coverage(policy, pool: MapPool, budget_step: int) -> dict[int, float]:
    """Budget → mean over the pool's maps of that budget's mean coverage."""
    table: dict[int, list[float]] = {}
    for grid_map, config in zip(pool.maps, pool.configs, strict=True):
        result = evaluate(policy, grid_map, budgets=protocol_budgets(config, budget_step),
                          config=config)  # fmt: skip
        for row in result.per_budget:
            table.setdefault(row["budget"], []).append(row["coverage_ratio"])
    return {b: float(np.mean(v)) for b, v in sorted(table.items())}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--agent", nargs="+", default=["general"], help="bundled agents' names or files")
    p.add_argument(
        "--rules", nargs="+", default=["no-finish-mask", "+finish-mask"],
        help="each agent flown with each of these rule changes (as --rule takes them, several "
        "joined by commas; own: the file's rules)",
    )  # fmt: skip
    p.add_argument("--size", type=int, default=16)
    p.add_argument("--maps", type=int, default=32)
    p.add_argument("--first-seed", type=int, default=VALIDATION_SEEDS.start + 100)
    p.add_argument("--budget-step", type=int, default=5)
    args = p.parse_args(argv)
    seeds = range(args.first_seed, args.first_seed + args.maps)
    check_seeds(args.first_seed, args.maps, "validation", VALIDATION_SEEDS)
    pool = MapPool.generate((args.size,), args.maps, args.first_seed)
    columns = {"safe-greedy": make_planner("safe-greedy")}
    digests = {}
    for spec in args.agent:
        agent = load_agent(spec)
        digests[spec] = agent.metadata.get("digest")
        for change in args.rules:
            label, policy = agent_entry(spec, agent, None if change == "own" else change.split(","))
            columns[label] = policy
    tables = {label: per_budget_coverage(pol, pool, args.budget_step)
              for label, pol in columns.items()}  # fmt: skip
    budgets = list(tables["safe-greedy"])
    print("budget  " + "  ".join(f"{label:>34}" for label in tables))
    for b in budgets:
        print(f"{b:6d}  " + "  ".join(f"{100 * t[b]:33.2f}%" for t in tables.values()))
    print(json.dumps({
        "maps": f"generated {args.size}x{args.size}, seeds {seeds.start}..{seeds.stop - 1}",
        "agent_digests": digests, "budget_step": args.budget_step, "backend": "grid",
        "mean": {label: float(np.mean(list(t.values()))) for label, t in tables.items()},
    }))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
