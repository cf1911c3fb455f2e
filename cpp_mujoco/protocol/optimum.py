"""The optimum beside every protocol result: each episode's best mission (or its proven bound)
read from the exact planner's cache (:mod:`cpp_mujoco.protocol.optimum_cache`), never solved here.

Only the paper's calm MDP has a cached optimum: a result under the grid's wind option, whose
actions cost what the wind makes them, carries none. MuJoCo results of calm flights carry the
grid's optimum of the same episodes, as the limit their grid plan could reach.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from cpp_mujoco.protocol.optimum_cache import OptimumCache
from cpp_mujoco.util.resources import bundled_dir, repository_dir

DEFAULT_FOLDER = "results/optimum"


def default_folder() -> Path | None:
    """The committed cache: a checkout's ``results/optimum``, else the copy an installed wheel
    carries (None without either)."""
    root = repository_dir()
    if root is not None and (root / DEFAULT_FOLDER).is_dir():
        return root / DEFAULT_FOLDER
    try:
        return bundled_dir("optimum")
    except FileNotFoundError:
        return None


def optimum_of(
    grid_map, starts: np.ndarray, budgets: np.ndarray, fov_side: int, folder
) -> dict[str, np.ndarray]:
    """Per episode: best mission's coverage ratio, its bound's, and the solver's status ('' and
    NaN where the cache does not know the episode). Empty when no episode is known."""
    folder = default_folder() if folder is None else Path(os.fspath(folder))
    if folder is None:
        return {}
    cache = OptimumCache(folder, grid_map, fov_side)
    if not cache.entries:
        return {}
    targets = float(grid_map.target.sum())
    n = len(budgets)
    seen, bound = np.full(n, np.nan), np.full(n, np.nan)
    status = np.full(n, "", dtype=object)
    for i, (start, budget) in enumerate(zip(starts, budgets, strict=True)):
        entry = cache.get(tuple(start), int(budget))
        if entry is not None:
            seen[i], bound[i] = entry["seen"] / targets, entry["bound"] / targets
            status[i] = entry["status"]
    if not status.any():
        return {}
    return {"coverage": seen, "bound": bound, "status": status}


def optimum_summary(optimum: dict[str, np.ndarray], coverage: np.ndarray) -> dict:
    """Means over the episodes the cache knows: the best missions' coverage, the bound, the
    policy's gap to the best missions, and how many were proven."""
    known = optimum["status"] != ""
    statuses: dict[str, int] = {}
    for s in optimum["status"][known]:
        statuses[str(s)] = statuses.get(str(s), 0) + 1
    best = optimum["coverage"][known]
    return {
        "episodes_known": int(known.sum()),
        "statuses": dict(sorted(statuses.items())),
        "coverage_ratio": float(best.mean()),
        "bound_ratio": float(optimum["bound"][known].mean()),
        "gap_to_optimal": float((best - coverage[known]).mean()),
    }
