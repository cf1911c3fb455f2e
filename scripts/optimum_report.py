"""The policies against the optimum on maps A, B and C: the table of docs/optimum.md.

    python scripts/optimum_report.py --evaluate   # fly the policies, write results/optimum_abc.json
    python scripts/optimum_report.py --evaluate --policy general   # re-fly that policy's rows only
    python scripts/optimum_report.py              # write the table from that file into the docs
    python scripts/optimum_report.py --check      # exit 1 if a doc's table is not the file's

The optimum comes from the committed cache (results/optimum/, filled by ``cpp-mujoco optimum``);
each policy flies the paper's full protocol on the grid, and its gap to the best missions is
taken over the same episodes. The doc's table is written from the result file alone, so the
numbers in it are the file's.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULT = ROOT / "results" / "optimum_abc.json"
DOCS = (ROOT / "docs" / "optimum.md",)
BEGIN, END = "<!-- optimum-table:begin -->", "<!-- optimum-table:end -->"
MAPS = ("A", "B", "C")


def policies(name: str) -> list[tuple[str, object]]:
    from cpp_mujoco.agent import load_agent
    from cpp_mujoco.agent.value_beam import ValueBeamAgent
    from cpp_mujoco.planners import make_planner

    general = load_agent("general")
    return [
        ("safe-greedy", make_planner("safe-greedy")),
        ("beam-search", make_planner("beam-search")),
        (f"ddqn-{name}", load_agent(name)),
        ("general", general),
        ("general+value-beam", ValueBeamAgent(general)),
    ]


def evaluate_all(workers: int, budget_step: int, only: list[str] | None = None) -> dict:
    """Fly every policy on A, B and C and the best missions in MuJoCo; with ``only`` (policy
    labels), fly just those policies' grid rows and keep every other row of the committed file
    in its place (a re-installed agent is re-flown without re-flying the rest)."""
    from cpp_mujoco.maps import load_map
    from cpp_mujoco.planners import make_planner
    from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets
    from cpp_mujoco.protocol.optimum import default_folder
    from cpp_mujoco.util.io import atomic_write_text, json_default

    kept = json.loads(RESULT.read_text()) if only else None
    rows, physics = [], []
    for name in MAPS:
        grid_map = load_map(name)
        for label, policy in policies(name):
            if only and label not in only:
                rows.append(_kept_row(kept, name, label))
                continue
            result = evaluate(policy, grid_map, policy_name=label)
            if not result.optimum:
                raise SystemExit(f"optimum_report.py: no optimum cached for map {name}")
            rows.append(result.summary())
        if only:
            continue
        # the best missions flown in MuJoCo, calm air, from the committed cache
        optimal = make_planner("optimal", optimal={"cache_folder": default_folder()})
        budgets = protocol_budgets(step=budget_step)
        flown = evaluate(optimal, grid_map, backend="mujoco", budgets=budgets, workers=workers)
        physics.append(flown.summary())
    data = {"results": rows, "physics": kept["physics"] if only else physics}
    atomic_write_text(RESULT, json.dumps(data, indent=1, default=json_default))
    return data


def _kept_row(kept: dict, name: str, label: str) -> dict:
    """The committed file's row of ``label`` on map ``name``."""
    found = [r for r in kept["results"] if r["map"] == name and r["policy"] == label]
    if len(found) != 1:
        raise SystemExit(f"optimum_report.py: {RESULT.name} holds no single {label} row on {name}")
    return found[0]


def render(data: dict) -> str:
    from cpp_mujoco.review.optimum_table import optimum_abc_table

    return optimum_abc_table(data)


def with_table(doc: Path, text: str, table: str) -> str:
    from cpp_mujoco.review.optimum_table import replace_between

    try:
        return replace_between(text, BEGIN, END, table, where=doc)
    except ValueError as exc:
        raise SystemExit(f"optimum_report.py: {exc}") from None


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--evaluate", action="store_true", help="fly the policies first")
    p.add_argument("--workers", type=int, default=2, help="MuJoCo worker processes")
    p.add_argument("--budget-step", type=int, default=10, help="MuJoCo: every n-th budget")
    p.add_argument(
        "--policy", nargs="+", metavar="LABEL",
        help="with --evaluate: re-fly only these policies' rows (safe-greedy, beam-search, "
        "ddqn-A/-B/-C, general, general+value-beam), keeping the file's other rows and its "
        "MuJoCo flights",
    )  # fmt: skip
    p.add_argument("--check", action="store_true", help="exit 1 if the doc's table drifted")
    args = p.parse_args(argv)
    known = {"safe-greedy", "beam-search", "general", "general+value-beam"}
    known |= {f"ddqn-{m}" for m in MAPS}
    if args.policy and not args.evaluate:
        p.error("--policy goes with --evaluate")
    if unknown := set(args.policy or ()) - known:
        p.error(f"unknown policy {sorted(unknown)}; one of {sorted(known)}")
    if args.evaluate:
        data = evaluate_all(args.workers, args.budget_step, args.policy)
    else:
        data = json.loads(RESULT.read_text())
    table = render(data)
    for doc in DOCS:
        text = doc.read_text()
        wanted = with_table(doc, text, table)
        if args.check and wanted != text:
            print(f"{doc} does not hold the table of {RESULT}; run scripts/optimum_report.py")
            return 1
        if wanted != text:
            from cpp_mujoco.util.io import atomic_write_text

            atomic_write_text(doc, wanted)
    if not args.check:
        print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
