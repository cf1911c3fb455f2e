"""The policies against the optimum on maps A, B and C: the table of README.md and docs/optimum.md.

    python scripts/optimum_report.py --evaluate   # fly the policies, write results/optimum_abc.json
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
DOCS = (ROOT / "README.md", ROOT / "docs" / "optimum.md")
BEGIN, END = "<!-- optimum-table:begin -->", "<!-- optimum-table:end -->"
MAPS = ("A", "B", "C")


def policies(name: str) -> list[tuple[str, object]]:
    from cpp_mujoco.agent import load_agent
    from cpp_mujoco.planners import make_planner

    return [
        ("safe-greedy", make_planner("safe-greedy")),
        ("beam-search", make_planner("beam-search")),
        (f"ddqn-{name}", load_agent(name)),
        ("general", load_agent("general")),
    ]


def evaluate_all(workers: int, budget_step: int) -> dict:
    from cpp_mujoco.maps import load_map
    from cpp_mujoco.planners import make_planner
    from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets
    from cpp_mujoco.protocol.optimum import default_folder
    from cpp_mujoco.util.io import atomic_write_text, json_default

    rows, physics = [], []
    for name in MAPS:
        grid_map = load_map(name)
        for label, policy in policies(name):
            result = evaluate(policy, grid_map, policy_name=label)
            if not result.optimum:
                raise SystemExit(f"optimum_report.py: no optimum cached for map {name}")
            rows.append(result.summary())
        # the best missions flown in MuJoCo, calm air, from the committed cache
        optimal = make_planner("optimal", optimal={"cache_folder": default_folder()})
        budgets = protocol_budgets(step=budget_step)
        flown = evaluate(optimal, grid_map, backend="mujoco", budgets=budgets, workers=workers)
        physics.append(flown.summary())
    data = {"results": rows, "physics": physics}
    atomic_write_text(RESULT, json.dumps(data, indent=1, default=json_default))
    return data


def render(data: dict) -> str:
    """The Markdown table: per map the best missions (proven share, bound), per policy its
    coverage and its gap to the best missions."""
    by_map: dict[str, list[dict]] = {}
    for row in data["results"]:
        by_map.setdefault(row["map"], []).append(row)
    names = list(dict.fromkeys(r["policy"].split("-")[0] if r["policy"].startswith("ddqn")
                               else r["policy"] for r in data["results"]))  # fmt: skip
    head = ["map", "episodes", "proven optimal", "optimal", "bound"]
    head += [f"{n} (gap)" for n in names]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, rows in by_map.items():
        o = rows[0]["optimum"]
        proven = o["statuses"].get("optimal", 0)
        cells = [
            name, str(rows[0]["episodes"]), f"{proven} / {o['episodes_known']}",
            f"{o['coverage_ratio']:.2%}", f"{o['bound_ratio']:.2%}",
        ]  # fmt: skip
        for row in rows:
            gap = row["optimum"]["gap_to_optimal"] * 100
            cells.append(f"{row['coverage_ratio']:.2%} ({-gap:+.2f})")
        lines.append("| " + " | ".join(cells) + " |")
    policy_names = ", ".join(r["policy"] for r in data["results"][: len(names)])
    lines.append("")
    lines.append(
        f"Grid, full protocol per map ({policy_names}); gap = the policy's coverage minus the "
        "best missions', in points, over the same episodes. Written by "
        "`python scripts/optimum_report.py` from `results/optimum_abc.json`."
    )
    lines.append("")
    lines.extend(proven_share(name) for name in by_map)
    if data.get("physics"):
        lines.append("")
    for row in data.get("physics", []):
        o = row["optimum"]
        budgets = row["conditions"]["budgets"]
        lines.append(
            f"- map {row['map']}, the best missions flown in MuJoCo (calm, budgets "
            f"{budgets['min']}..{budgets['max']} every {budgets['step']}, {row['episodes']} "
            f"episodes): landing {row['landing_ratio']:.2%}, coverage {row['coverage_ratio']:.2%} "
            f"(the grid's best missions {o['coverage_ratio']:.2%}), "
            f"{row['energy_per_action_j']:.0f} J per action, {row['nfz_violations']} no-fly "
            "violations."
        )
    return "\n".join(lines)


def proven_share(name: str) -> str:
    """One map's cache in a line: how many episodes each solver proved at which time limit, how
    many are open and how far, the median and the slowest solve (read from the committed cache,
    so the line is the file's)."""
    import numpy as np

    from cpp_mujoco.maps import load_map
    from cpp_mujoco.protocol.optimum import default_folder
    from cpp_mujoco.protocol.optimum_cache import OptimumCache

    entries = OptimumCache(default_folder(), load_map(name)).entries
    proven: dict[str, int] = {}
    for e in entries.values():
        if e["status"] == "optimal":
            by = f"{e['solver']} ({e['time_limit_s']:g} s limit)"
            proven[by] = proven.get(by, 0) + 1
    open_gaps = [e["bound"] - e["seen"] for e in entries.values() if e["status"] != "optimal"]
    times = np.array([e["time_s"] for e in entries.values()])
    slowest = max((e["time_s"], k) for k, e in entries.items() if e["status"] == "optimal")
    row, col, budget = slowest[1].split(",")
    text = f"- map {name}, {len(entries)} episodes: proven " + ", ".join(
        f"{n} by {by}" for by, n in sorted(proven.items(), key=lambda kv: -kv[1])
    )
    if open_gaps:
        text += (f"; not proven {len(open_gaps)} (the best mission {min(open_gaps)}–"
                 f"{max(open_gaps)} targets under the bound)")  # fmt: skip
    return text + (
        f"; solve time median {np.median(times):.1f} s, slowest proven {slowest[0]:.1f} s "
        f"(start ({row}, {col}), {budget} units)."
    )


def with_table(doc: Path, text: str, table: str) -> str:
    if BEGIN not in text or END not in text:
        raise SystemExit(f"optimum_report.py: {doc} lacks the markers {BEGIN} … {END}")
    before, rest = text.split(BEGIN, 1)
    _, after = rest.split(END, 1)
    return f"{before}{BEGIN}\n{table}\n{END}{after}"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--evaluate", action="store_true", help="fly the policies first")
    p.add_argument("--workers", type=int, default=2, help="MuJoCo worker processes")
    p.add_argument("--budget-step", type=int, default=10, help="MuJoCo: every n-th budget")
    p.add_argument("--check", action="store_true", help="exit 1 if the doc's table drifted")
    args = p.parse_args(argv)
    if args.evaluate:
        data = evaluate_all(args.workers, args.budget_step)
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
