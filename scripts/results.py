"""Full-protocol table: bundled DDQN agents vs the reference planners on maps A, B, C.

python scripts/results.py [--maps A B C] [--json results.json]
"""

from __future__ import annotations

import argparse
import json

from cpp_mujoco.agent import load_agent
from cpp_mujoco.evaluate import PAPER_LANDING_RATIO, evaluate
from cpp_mujoco.planners import make_planner


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--maps", nargs="+", default=["A", "B", "C"])
    p.add_argument("--json", default=None, help="also write the rows here")
    args = p.parse_args(argv)
    rows = []
    print(f"{'map':4} {'policy':12} {'landing':>8} {'coverage':>9} {'paper landing':>14}")
    for m in args.maps:
        policies = {"ddqn": load_agent(m), "safe-greedy": make_planner("safe-greedy")}
        for name, policy in policies.items():
            r = evaluate(policy, m)
            rows.append(
                {
                    "map": m,
                    "policy": name,
                    "landing_ratio": r.landing_ratio,
                    "coverage_ratio": r.coverage_ratio,
                }
            )
            paper = PAPER_LANDING_RATIO.get(m) if name == "ddqn" else None
            paper_txt = f"{paper:.4f}" if paper else ""
            print(f"{m:4} {name:12} {r.landing_ratio:8.4f} {r.coverage_ratio:9.4f} {paper_txt:>14}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
