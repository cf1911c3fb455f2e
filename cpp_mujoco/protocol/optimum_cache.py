"""Solved episodes kept on disk: one JSON file per map, keyed by start cell and budget.

A best mission costs seconds to minutes of solver time, so it is solved once: an entry is reused
whenever it is proven optimal or was solved with at least the time limit asked for now (a longer
limit may improve a mission that was not proven, and starts from it). The file names the map's
digest and field of view; a file of another map, another format or a broken one is refused with
a clear error and never overwritten. Writes go through :func:`cpp_mujoco.util.io.atomic_write_text`,
so an interrupted solve keeps every entry saved before it and resumes from there.

The entries are consistent with each other before they are written (:func:`tighten`): a
mission of a smaller budget also flies with a larger one (it lands sooner), a mission from one
landing cell also flies from another after the flight between them, and the bounds likewise.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.graph import MapGraph, build_graph
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
        tighten(self.entries, build_graph(self.grid_map, self.fov_side))
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


def _path(g: MapGraph, src: int, dst: int) -> list[int]:
    """The moves of one shortest accepted flight from flat cell ``src`` to ``dst``."""
    to_dst = g.distance_from([dst])[0]  # symmetric between flyable cells: d(·, dst)
    moves, cell = [], src
    while cell != dst:
        nxt = g.safety.next_cell[cell, :LAND]
        closer = g.safety.accepted[cell, :LAND] & (to_dst[nxt] == to_dst[cell] - 1)
        a = int(np.flatnonzero(closer)[0])
        moves.append(a)
        cell = int(nxt[a])
    return moves


def tighten(entries: dict[str, dict[str, Any]], g: MapGraph) -> int:
    """Make the entries consistent with each other, in place; the number of entries changed.

    A mission of budget b' from landing cell s' is, after the d(s, s') moves from s to s', a
    mission of any budget b >= b' + d(s, s') from s, and it sees at least as much: an entry takes
    the best such mission (flown under the MDP's rules, its own count). Every mission of budget b
    from s is so part of one of budget b + d(s', s) from s': an entry takes the lowest such bound.
    The budget alone (s' = s, d = 0: a mission of a smaller budget lands sooner) makes each
    start's entries monotone. An entry changed so says where from (``tightened_from``: the
    episodes whose mission and bound it holds) and is optimal once its mission meets its bound;
    an entry the others contradict is a :class:`CacheError`."""
    keys = [k for k, e in entries.items() if e["status"] != "infeasible"]
    if not keys:
        return 0
    width = g.grid_map.shape[1]
    parts = np.array([_order(k) for k in keys], dtype=np.int64)
    cells = parts[:, 0] * width + parts[:, 1]
    starts, index = np.unique(cells, return_inverse=True)
    between = g.distance_from(starts)[:, starts].astype(np.int64)[index[:, None], index[None, :]]
    budget = parts[:, 2]
    _refuse_infeasible(entries, g, parts, budget)
    changed: set[str] = set()
    for _ in range(len(keys)):  # each pass can only raise a mission's count: few passes
        seen = np.array([entries[k]["seen"] for k in keys])
        bound = np.array([entries[k]["bound"] for k in keys])
        flies = budget[None, :] + between <= budget[:, None]  # [i, j]: j's mission flies for i
        best = np.where(flies, seen[None, :], -1).argmax(axis=1)
        holds = budget[None, :] >= budget[:, None] + between.T  # [i, j]: j's bound holds for i
        low = np.where(holds, bound[None, :], np.iinfo(np.int64).max).argmin(axis=1)
        moved = False
        for i in np.flatnonzero((seen[best] > seen) | (bound[low] < bound)):
            key, e = keys[i], dict(entries[keys[i]])
            origin = e.get("tightened_from", {})
            if seen[best[i]] > seen[i]:
                j = best[i]
                actions = _path(g, int(cells[i]), int(cells[j])) + list(entries[keys[j]]["actions"])
                count, landed = g.fly(int(cells[i]), np.array(actions, dtype=np.int64))
                if not landed or count < seen[j] or len(actions) > budget[i]:
                    raise CacheError(f"episode {keys[j]}'s mission does not fly to its count")
                e.update(seen=int(count), actions=actions)
                origin = {**origin, "mission": keys[j]}
            if bound[low[i]] < bound[i]:
                e["bound"] = int(bound[low[i]])
                origin = {**origin, "bound": keys[low[i]]}
            if e["seen"] > e["bound"]:
                raise CacheError(
                    f"the optimum cache contradicts itself at episode {key}: a mission sees "
                    f"{e['seen']} targets, the bound is {e['bound']} (from {origin})"
                )
            e["status"] = "optimal" if e["seen"] >= e["bound"] else "feasible"
            entries[key] = {**e, "tightened_from": origin}
            changed.add(key)
            moved = True
        if not moved:
            break
    return len(changed)


def _refuse_infeasible(entries, g: MapGraph, parts: np.ndarray, budget: np.ndarray) -> None:
    """An episode said to have no way home where a mission of the others proves one."""
    width = g.grid_map.shape[1]
    for key, e in entries.items():
        if e["status"] != "infeasible":
            continue
        r, c, b = _order(key)
        d = g.distance_from([r * width + c])[0][parts[:, 0] * width + parts[:, 1]]
        if (budget + d <= b).any():
            raise CacheError(
                f"the optimum cache contradicts itself at episode {key}: it has no way home, "
                "a mission of another episode gives one"
            )


def _order(key: str) -> tuple[int, ...]:
    return tuple(int(v) for v in key.split(","))
