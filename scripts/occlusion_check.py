"""Physics vs grid coverage on a map set with obstacles: the cells one backend counts and the
other does not (``cpp_mujoco.physics.occlusion_check.compare_coverage``).

    python scripts/occlusion_check.py --map-set city32-v1 --budgets 75 125

flies each map's first landing cell with every budget given: the policy on the grid, the same
actions in calm MuJoCo air. Writes ``results/occlusion_<set>_fov<side>.json`` (one row per
episode, with its map, digest, policy, backend and conditions, and the totals), which the
physics page's table is written from (``scripts/results_docs.py``).
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str] | None = None) -> int:
    from cpp_mujoco.map_sets.sets import load_map_set, map_set_spec
    from cpp_mujoco.physics.config import PhysicsConfig
    from cpp_mujoco.physics.occlusion_check import compare_coverage
    from cpp_mujoco.planners import make_planner
    from cpp_mujoco.review.report import script_command
    from cpp_mujoco.util.io import atomic_write_text

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--map-set", default="city32-v1", help="a held-out set with obstacles")
    p.add_argument("--budgets", nargs="+", type=int, default=[75, 125], help="per landing cell")
    p.add_argument("--planner", default="safe-greedy", help="the policy flown on the grid")
    p.add_argument("--first", type=int, default=None, help="only the set's first N maps")
    p.add_argument("--fov-side", type=int, default=3, help="the camera's square, cells")
    p.add_argument("--out", default=str(ROOT / "results"), help="folder for the JSON")
    args = p.parse_args(argv)
    command = script_command(__file__, argv)
    spec = map_set_spec(args.map_set)
    config = PhysicsConfig()
    rows, seen, extra, missing = [], 0, 0, 0
    for grid_map in load_map_set(args.map_set, first=args.first):
        start = tuple(int(v) for v in divmod(int(grid_map.landing.argmax()), grid_map.shape[1]))
        gaps = compare_coverage(
            grid_map, [start] * len(args.budgets), args.budgets,
            make_planner(args.planner, fov_side=args.fov_side), config, fov_side=args.fov_side,
        )  # fmt: skip
        for gap in gaps:
            seen, extra, missing = (
                seen + gap.grid_seen,
                extra + len(gap.extra),
                missing + len(gap.missing),
            )
            rows.append({
                **grid_map.identity(), "policy": args.planner, "backend": "grid vs mujoco",
                "start": list(start), "budget": gap.budget, "grid_seen": gap.grid_seen,
                "physics_seen": gap.physics_seen, "extra": [list(c) for c in gap.extra],
                "missing": [list(c) for c in gap.missing], "actions": len(gap.actions),
                "physics_steps": gap.physics_steps, "crash_reason": gap.crash_reason,
                "conditions": {"map_set": spec.identity(), "fov_side": args.fov_side,
                               "wind": "calm", "physics_config": asdict(config)},
            })  # fmt: skip
        counts = [sum(g.grid_seen for g in gaps), sum(len(g.extra) for g in gaps)]
        counts.append(sum(len(g.missing) for g in gaps))
        print(f"{grid_map.label}: grid {counts[0]}, extra {counts[1]}, missing {counts[2]}")
    totals = {
        "episodes": len(rows), "grid_seen": seen, "extra": extra, "missing": missing,
        "extra_share": extra / seen if seen else 0.0,
        "missing_share": missing / seen if seen else 0.0,
        "crashes": sum(r["crash_reason"] is not None for r in rows),
    }  # fmt: skip
    out = Path(args.out) / f"occlusion_{args.map_set}_fov{args.fov_side}.json"
    atomic_write_text(out, json.dumps({"command": command, "totals": totals, "results": rows},
                                      indent=1))  # fmt: skip
    print(f"{totals}\nwrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
