"""The paper-style results: bundled DDQN agents vs the reference planners on maps A, B, C.

    python scripts/results.py [--maps A B C] [--out out/results] [--budget-step N]

Full protocol on the grid (every landing cell × every budget 25..75, greedy). Writes, per map, the
coverage-per-budget figure against the planners and the upper bound (the paper's Fig. 3), example
trajectories at three budgets for each policy (Fig. 2), every result as JSON, and ``results.txt``:
landing ratio vs the paper's, coverage vs the safe greedy and beam-search planners (the same table
with its conditions and unrounded numbers in ``results.json``), and ``index.html``, the page of it
all.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cpp_mujoco.agent import load_agent
from cpp_mujoco.maps import GridMap
from cpp_mujoco.missions.lineup import run_evaluation
from cpp_mujoco.planners import make_planner
from cpp_mujoco.review.report import script_command, write_report
from cpp_mujoco.review.results import (
    PAPER_COLUMNS,
    Table,
    paper_row,
    write_rendered,
    write_tables,
)


def policies(grid_map: GridMap):
    """The bundled agent of a bundled map and the two reference planners."""
    if not grid_map.bundled:
        raise SystemExit(f"results.py: map {grid_map.label!r} is not bundled; it has no agent")
    return [
        ("ddqn", load_agent(grid_map.name)),
        ("safe-greedy", make_planner("safe-greedy")),
        ("beam-search", make_planner("beam-search")),
    ]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--maps", nargs="+", default=["A", "B", "C"], help="bundled maps")
    p.add_argument("--out", default="out/results", help="folder for figures, JSON, results.txt")
    p.add_argument(
        "--budget-step", type=int, default=1,
        help="every n-th budget, the largest always included (default: 1, the full protocol)",
    )  # fmt: skip
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.budget_step < 1:
        p.error(f"--budget-step must be >= 1, got {args.budget_step}")
    results = run_evaluation(
        args.maps, policies, out, progress=sys.stderr.isatty(), budget_step=args.budget_step
    )
    table = Table("the bundled agents against the paper and the planners", PAPER_COLUMNS)
    for per_map in results.values():
        by = {r.policy_name: r for r in per_map}
        table.rows.append(paper_row(by["ddqn"], by["safe-greedy"], by["beam-search"]))
    write_tables(out / "results.json", {"paper": table})
    write_rendered(out / "results.txt", {"paper": table})
    write_report(out, script_command(__file__, argv))
    print(f"\n{table.render()}\n\nfigures, JSON and results.txt: {out}/ (page: index.html)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
