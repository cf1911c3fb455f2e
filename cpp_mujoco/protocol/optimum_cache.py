"""Solved episodes kept on disk: one JSON file per map, keyed by start cell and budget.

A best mission costs seconds to minutes of solver time, so it is solved once: an entry is reused
whenever it is proven optimal or was solved with at least the time limit asked for now (a longer
limit may improve a mission that was not proven, and starts from it). The file names the map's
digest and field of view; a file of another map, another format or a broken one is refused with
a clear error and never overwritten. Writes go through :func:`cpp_mujoco.util.io.atomic_write_text`,
so an interrupted solve keeps every entry saved before it and resumes from there.

The entries of one start are consistent across budgets before they are written
(:func:`tighten_by_budget`): a mission of a smaller budget also flies with a larger one (it lands
sooner), and a bound of a larger budget also holds for a smaller one.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from cpp_mujoco.maps import GridMap
from cpp_mujoco.util.io import atomic_write_text

FORMAT = "cpp_mujoco.optimum/1"
ENTRY_KEYS = ("seen", "bound", "status", "time_s", "time_limit_s", "workers", "solver", "actions")


class CacheError(ValueError):
    """A cache file that is not this map's, not this format, or broken."""


def episode_key(start: tuple[int, int], budget: int) -> str:
    return f"{int(start[0])},{int(start[1])},{int(budget)}"


class OptimumCache:
    """The solved episodes of one map (and field of view) under ``folder``."""

    def __init__(self, folder: str | os.PathLike | None, grid_map: GridMap, fov_side: int = 3):
        self.grid_map = grid_map
        self.fov_side = int(fov_side)
        # named by digest: a planner knows the map only from its observations
        self.path = None if folder is None else Path(folder) / f"{grid_map.digest}.json"
        self.label = None if grid_map.name == "observed" else grid_map.label
        self.entries: dict[str, dict[str, Any]] = self._read()

    @classmethod
    def in_memory(cls, grid_map: GridMap, fov_side: int = 3) -> OptimumCache:
        """A cache that is never written (a planner without a folder)."""
        return cls(None, grid_map, fov_side)

    def _read(self) -> dict[str, dict[str, Any]]:
        if self.path is None or not self.path.exists():
            return {}
        where = f"optimum cache {self.path}"
        try:
            data = json.loads(self.path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise CacheError(f"{where} cannot be read ({exc}); move it away to solve again") from (
                None
            )
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise CacheError(f"{where} is not a {FORMAT} file; refusing to use or overwrite it")
        if data.get("map_digest") != self.grid_map.digest:
            raise CacheError(
                f"{where} belongs to map digest {data.get('map_digest')!r}, not "
                f"{self.grid_map.label} ({self.grid_map.digest}); refusing to use or overwrite it"
            )
        if data.get("fov_side") != self.fov_side:
            raise CacheError(
                f"{where} was solved for field of view {data.get('fov_side')!r}, not "
                f"{self.fov_side}; refusing to use or overwrite it"
            )
        self.label = self.label or data.get("map")
        entries = data.get("entries")
        if not isinstance(entries, dict) or not all(
            isinstance(e, dict) and set(ENTRY_KEYS) <= set(e) for e in entries.values()
        ):
            raise CacheError(f"{where} has malformed entries; refusing to use or overwrite it")
        return entries

    def get(self, start: tuple[int, int], budget: int) -> dict[str, Any] | None:
        return self.entries.get(episode_key(start, budget))

    def usable(self, start: tuple[int, int], budget: int, solver: str, time_limit_s: float) -> bool:
        """Known and not worth solving again: proven, or solved by ``solver`` (its name and
        release, as results give it; the release may differ) with at least ``time_limit_s``."""
        entry = self.get(start, budget)
        return entry is not None and (
            entry["status"] in ("optimal", "infeasible")
            or (entry["time_limit_s"] >= time_limit_s
                and entry["solver"].split()[0] == solver.split()[0])
        )  # fmt: skip

    def put(self, start: tuple[int, int], budget: int, mission, time_limit_s: float,
            workers: int, solver: str) -> None:  # fmt: skip
        old = self.get(start, budget)
        actions, seen, bound = mission.actions, mission.seen, mission.bound
        if old is not None:  # both bounds hold; never trade a mission for a worse one
            bound = min(bound, old["bound"])
            if old["seen"] > seen:
                actions, seen = np.asarray(old["actions"]), old["seen"]
        status = "optimal" if seen >= bound and mission.status == "feasible" else mission.status
        self.entries[episode_key(start, budget)] = {
            "seen": int(seen),
            "bound": int(bound),
            "status": status,
            "time_s": round(float(mission.time_s), 3),
            "time_limit_s": float(time_limit_s),
            "workers": int(workers),
            "solver": solver,
            "actions": [int(a) for a in actions],
        }

    def save(self) -> None:
        """Write every entry, merged with what the file holds now (another process solving the
        same map keeps its entries: of two entries for one episode the better mission and the
        lower bound are kept)."""
        if self.path is not None and self.path.exists():
            for key, theirs in self._read().items():
                mine = self.entries.get(key)
                if mine is None:
                    self.entries[key] = theirs
                elif theirs["seen"] > mine["seen"] or theirs["bound"] < mine["bound"]:
                    better = theirs if theirs["seen"] >= mine["seen"] else mine
                    bound = min(theirs["bound"], mine["bound"])
                    status = "optimal" if better["seen"] >= bound else better["status"]
                    self.entries[key] = {**better, "bound": bound, "status": status}
        tighten_by_budget(self.entries)
        data = {
            "format": FORMAT,
            "map": self.label,
            "map_digest": self.grid_map.digest,
            "map_shape": list(self.grid_map.shape),
            "fov_side": self.fov_side,
            "num_targets": int(self.grid_map.target.sum()),
            "entries": dict(sorted(self.entries.items(), key=lambda kv: _order(kv[0]))),
        }
        if self.path is None:
            raise ValueError("an in-memory optimum cache has no file to save to")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(self.path, json.dumps(data, indent=1))


def tighten_by_budget(entries: dict[str, dict[str, Any]]) -> int:
    """Make each start's entries monotone in the budget, in place; the number of entries changed.

    Every mission of budget b' < b is a mission of budget b (it lands after at most b' actions),
    so an entry takes the best mission of any smaller budget; every mission of budget b is one of
    any larger budget, so an entry takes the lowest bound of any larger budget. An entry changed so
    says where from (``tightened_from``: the budgets whose mission and bound it holds), and is
    optimal once its mission meets its bound."""
    by_start: dict[tuple[int, int], list[int]] = {}
    for key in entries:
        r, c, b = _order(key)
        by_start.setdefault((r, c), []).append(b)
    changed = 0
    for (r, c), budgets in by_start.items():
        budgets.sort()
        lowest: list[tuple[int, int]] = []  # (bound, its budget) from the largest budget down
        for b in reversed(budgets):
            e = entries[episode_key((r, c), b)]
            if e["status"] != "infeasible" and (not lowest or e["bound"] < lowest[-1][0]):
                lowest.append((e["bound"], b))
            else:
                lowest.append(lowest[-1] if lowest else (e["bound"], b))
        lowest.reverse()
        best: tuple[int, int] | None = None  # (seen, its budget) from the smallest budget up
        for b, (bound, bound_budget) in zip(budgets, lowest, strict=True):
            key = episode_key((r, c), b)
            e = entries[key]
            if e["status"] == "infeasible":
                continue
            if best is None or e["seen"] >= best[0]:
                best = (e["seen"], b)
            mission_budget = best[1]
            if mission_budget == b and (bound_budget == b or bound >= e["bound"]):
                continue
            source = entries[episode_key((r, c), mission_budget)]
            seen, bound = source["seen"], min(bound, e["bound"])
            if seen > bound:
                raise CacheError(
                    f"the optimum cache contradicts itself at start ({r}, {c}): budget "
                    f"{mission_budget}'s mission sees {seen} targets, budget {bound_budget}'s "
                    f"bound is {bound}"
                )
            entries[key] = {
                **e,
                "seen": int(seen),
                "bound": int(bound),
                "status": "optimal" if seen >= bound else "feasible",
                "actions": list(source["actions"]),
                "tightened_from": {"mission": mission_budget, "bound": bound_budget},
            }
            changed += 1
    return changed


def _order(key: str) -> tuple[int, ...]:
    return tuple(int(v) for v in key.split(","))
