"""The exact search against the solvers' proofs: on every episode of A, B and C that HiGHS or
CP-SAT proved, it must find a mission of the optimum's count and prove that none sees one more.

    python scripts/search_agreement.py                  # A, B and C; writes the file below
    python scripts/search_agreement.py --maps B --step 1

Episodes whose proof came from the solvers themselves are asked (not those the cache's
``tighten`` carried from the episodes beside them, nor those the search closed); ``--step N``
asks every Nth budget of each start. Writes results/search_agreement.json: per map how many
episodes agreed, disagreed (listed) or ran out of time, and the slowest pair of questions.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULT = ROOT / "results" / "search_agreement.json"


def check_map(name: str, step: int, time_limit: float) -> dict:
    from cpp_mujoco.grid.graph import build_graph
    from cpp_mujoco.maps import load_map
    from cpp_mujoco.planners.optimal_search import CoverageSearch, SearchOptions
    from cpp_mujoco.protocol.optimum import default_folder
    from cpp_mujoco.protocol.optimum_cache import OptimumCache

    grid_map = load_map(name)
    g = build_graph(grid_map)
    targets = int(grid_map.target.sum())
    entries = OptimumCache(default_folder(), grid_map).entries
    by_start: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for key, e in entries.items():
        row, col, budget = map(int, key.split(","))
        by_solver = "tightened_from" not in e and not e["solver"].startswith("key-target")
        if e["status"] == "optimal" and by_solver:
            by_start.setdefault((row, col), []).append((budget, e["seen"]))
    agreed, unknown, disagreed, slowest, keys = 0, 0, [], 0.0, 0
    options = SearchOptions(time_limit_s=time_limit)
    for (row, col), episodes in sorted(by_start.items()):
        search = CoverageSearch(g, row * grid_map.shape[1] + col, options)
        keys = int(search.keys.size)
        for budget, seen in sorted(episodes)[::step]:
            found = search.ask(budget, seen)
            more = search.ask(budget, seen + 1) if seen < targets else None
            answers = (found.status, more.status if more else "none")
            slowest = max(slowest, found.time_s + (more.time_s if more else 0.0))
            if "unknown" in answers:
                unknown += 1
            elif answers == ("found", "none"):
                agreed += 1
            else:
                disagreed.append({"start": [row, col], "budget": budget, "optimum": seen,
                                  "answers": list(answers)})  # fmt: skip
    return {
        "map": name,
        "map_digest": grid_map.digest,
        "asked": agreed + unknown + len(disagreed),
        "agreed": agreed,
        "unknown": unknown,
        "disagreed": disagreed,
        "slowest_s": round(slowest, 2),
        "key_targets": keys,
    }


def main(argv=None) -> int:
    from cpp_mujoco.util.io import atomic_write_text

    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--maps", nargs="+", default=["A", "B", "C"])
    p.add_argument("--step", type=int, default=1, help="every Nth budget of each start")
    p.add_argument("--time-limit", type=float, default=60.0, help="seconds per question")
    args = p.parse_args(argv)
    rows = []
    for name in args.maps:
        rows.append(check_map(name, args.step, args.time_limit))
        print(json.dumps(rows[-1]), flush=True)
    data = {"step": args.step, "time_limit_s": args.time_limit, "maps": rows}
    atomic_write_text(RESULT, json.dumps(data, indent=1))
    return int(any(r["disagreed"] for r in rows))


if __name__ == "__main__":
    sys.exit(main())
