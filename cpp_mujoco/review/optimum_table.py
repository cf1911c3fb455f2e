"""The exact planner's answers summarised: how many episodes were proven, the best missions'
mean coverage beside the proven bound, and what solving cost."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cpp_mujoco.maps import GridMap


def optimum_figures(grid_map: GridMap, entries: list[dict]) -> dict:
    """Mean coverage of the best missions found and of the bounds, status counts, solve times."""
    targets = int(grid_map.target.sum())
    seen = np.array([e["seen"] for e in entries], dtype=np.float64)
    bound = np.array([e["bound"] for e in entries], dtype=np.float64)
    times = np.array([e["time_s"] for e in entries], dtype=np.float64)
    statuses: dict[str, int] = {}
    for e in entries:
        statuses[e["status"]] = statuses.get(e["status"], 0) + 1
    return {
        "episodes": len(entries),
        "statuses": dict(sorted(statuses.items())),
        "best_found": float(seen.mean() / targets),
        "bound": float(bound.mean() / targets),
        "median_time_s": float(np.median(times)),
        "max_time_s": float(times.max()),
        "solvers": sorted({e["solver"] for e in entries}),
        "time_limits_s": sorted({e["time_limit_s"] for e in entries}),
    }


def optimum_summary(grid_map: GridMap, entries: list[dict], path: Path | None) -> str:
    f = optimum_figures(grid_map, entries)
    counts = ", ".join(f"{n} {s}" for s, n in f["statuses"].items())
    return (
        f"map {grid_map.label} ({grid_map.digest}): {f['episodes']} episodes, {counts}; best "
        f"missions {f['best_found']:.2%} coverage, bound {f['bound']:.2%}; solve time median "
        f"{f['median_time_s']:.1f} s, max {f['max_time_s']:.1f} s ({', '.join(f['solvers'])}, "
        f"limit {', '.join(f'{t:g}' for t in f['time_limits_s'])} s)"
        + (f"; cache {path}" if path else "")
    )
