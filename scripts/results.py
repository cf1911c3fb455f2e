"""The paper-style results: bundled DDQN agents vs the reference planners on maps A, B, C.

    python scripts/results.py [--maps A B C] [--out out/results]

Full protocol on the grid (every landing cell × every budget 25..75, greedy). Writes, per map, the
coverage-per-budget figure against the planners and the upper bound (the paper's Fig. 3), example
trajectories at three budgets for each policy (Fig. 2), every result as JSON, and ``results.txt``:
landing ratio vs the paper's, coverage vs the safe greedy and beam-search planners.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from cpp_mujoco.agent import load_agent
from cpp_mujoco.cli import run_evaluation
from cpp_mujoco.evaluate import PAPER_LANDING_RATIO, atomic_write_text
from cpp_mujoco.planners import make_planner
from cpp_mujoco.review.tables import format_table


def policies(map_name: str):
    return [
        ("ddqn", load_agent(map_name)),
        ("safe-greedy", make_planner("safe-greedy")),
        ("beam-search", make_planner("beam-search")),
    ]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--maps", nargs="+", default=["A", "B", "C"])
    p.add_argument("--out", default="out/results", help="folder for figures, JSON, results.txt")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = run_evaluation(args.maps, policies, out)
    rows = []
    for per_map in results.values():
        by = {r.policy_name: r for r in per_map}
        agent, greedy, beam = by["ddqn"], by["safe-greedy"], by["beam-search"]
        paper = PAPER_LANDING_RATIO[agent.map_name]
        crashes = int((~agent.landed).sum())
        rows.append(
            {
                "map": agent.map_name,
                "landing": f"{agent.landing_ratio:.2%} ({crashes} of {agent.landed.size} crash)",
                "paper landing": f"{paper:.2%}",
                "coverage": f"{agent.coverage_ratio:.2%}",
                "safe greedy": f"{greedy.coverage_ratio:.2%}",
                "beam search": f"{beam.coverage_ratio:.2%}",
                "bar met": "yes"
                if agent.landing_ratio >= paper and agent.coverage_ratio >= greedy.coverage_ratio
                else "no",
            }
        )
    table = format_table(rows, list(rows[0]))
    atomic_write_text(out / "results.txt", table + "\n")
    print(f"\n{table}\n\nfigures, JSON and results.txt: {out}/")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
