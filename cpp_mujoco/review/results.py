"""Results tables: the row builders, the evaluation run behind them, and their JSON.

The ``evaluate`` command, the demo and the scripts (``results.py``, ``transfer.py``) build every
results table here and render it with :func:`~cpp_mujoco.util.tables.format_table`, so a
number has one format and one label wherever it is shown. Each row carries its map's label (a
user's ``A.png`` is ``A-<digest>``, never map A) and digest, the policy, the backend, the raw
numbers beside the shown cells, and the conditions of its results. A table's JSON states the
conditions all its rows share once, and in each row only what differs (a wind speed, budgets).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cpp_mujoco.maps import GridMap
from cpp_mujoco.protocol.evaluate import PAPER_LANDING_RATIO, split_conditions
from cpp_mujoco.review.report_conditions import weather_summary
from cpp_mujoco.util.io import atomic_write_text, json_plain
from cpp_mujoco.util.tables import format_table

PROTOCOL_COLUMNS = [
    "map", "policy", "episodes", "landing", "coverage", "optimal", "gap to optimal",
    "paper landing", "seconds",
]  # fmt: skip
DEMO_GRID_COLUMNS = [
    "map",
    "policy",
    "landing",
    "coverage",
    "optimal",
    "gap to optimal",
    "paper landing",
]
TRANSFER_COLUMNS = [
    "map", "policy", "episodes", "grid landing", "mujoco landing", "grid coverage",
    "mujoco coverage", "J/action", "nfz viol.",
]  # fmt: skip
WIND_COLUMNS = [
    "map", "policy", "wind m/s", "landing", "coverage", "J/action", "crashes", "nfz viol."
]  # fmt: skip
PAPER_COLUMNS = [
    "map", "landing", "paper landing", "coverage", "safe greedy", "beam search", "bar met"
]  # fmt: skip
_IDENTITY = ("map", "map_source", "map_bundled", "map_digest", "map_shape")


def file_part(name: str) -> str:
    """A policy or map name as a file-name part (``ddqn[runs/x.pt]`` → ``ddqn_runs_x.pt``)."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("_")


def paper_landing(grid_map: GridMap) -> float | None:
    """The paper's landing ratio, only beside the bundled map it was measured on."""
    return PAPER_LANDING_RATIO.get(grid_map.name) if grid_map.bundled else None


def _pct(ratio: float) -> str:
    return f"{ratio:.2%}"


def _numbers(result) -> dict[str, Any]:
    """The result's headline numbers, unrounded (identity and conditions are kept elsewhere)."""
    drop = {*_IDENTITY, "policy", "backend", "conditions"}
    return {k: v for k, v in result.summary().items() if k not in drop}


def _row(result, cells: dict, values: Any, conditions: Any, backend: str | None = None) -> dict:
    return {
        "map": result.map_name,
        "policy": result.policy_name,
        **cells,
        "backend": backend or result.backend,
        "map_digest": result.grid_map.digest,
        "values": values,
        "conditions": conditions,
    }


def _same_episodes(*results) -> None:
    """Rows that compare results must compare like with like, or the row is wrong silently."""
    first = results[0]
    for other in results[1:]:
        if other.grid_map.digest != first.grid_map.digest:
            raise ValueError(f"results of maps {first.map_name!r} and {other.map_name!r} compared")
        if sorted(set(other.budgets.tolist())) != sorted(set(first.budgets.tolist())):
            raise ValueError(f"results over different budgets compared on map {first.map_name!r}")


def optimum_cells(result) -> dict[str, str]:
    """The best missions' coverage and the policy's gap to them over the same episodes; where
    some were not proven, the bound too, and where the cache misses episodes, how many it has."""
    if not result.optimum:
        return {"optimal": "-", "gap to optimal": "-"}
    return optimum_summary_cells(result.summary()["optimum"], int(result.landed.size))


def optimum_summary_cells(o: dict | None, episodes: int) -> dict[str, str]:
    """:func:`optimum_cells` from a result's summary (``summary()["optimum"]``, as its JSON
    keeps it) and its episode count."""
    if not o:
        return {"optimal": "-", "gap to optimal": "-"}
    best = _pct(o["coverage_ratio"])
    if o["statuses"].get("optimal", 0) < o["episodes_known"]:
        best += f" (bound {_pct(o['bound_ratio'])})"
    if o["episodes_known"] < episodes:
        best += f" [{o['episodes_known']} ep.]"
    return {"optimal": best, "gap to optimal": f"{o['gap_to_optimal'] * 100:.2f} pt"}


def protocol_row(result, seconds: float | None = None) -> dict:
    """One policy's protocol on one map (either backend); ``seconds``: its wall time."""
    paper = paper_landing(result.grid_map)
    cells = {
        "episodes": int(result.landed.size),
        "landing": _pct(result.landing_ratio),
        "coverage": _pct(result.coverage_ratio),
        **optimum_cells(result),
        "paper landing": _pct(paper) if paper else "-",
    }
    if seconds is not None:
        cells["seconds"] = f"{seconds:.2f}"
    return _row(result, cells, _numbers(result), result.conditions)


def transfer_row(grid, physics) -> dict:
    """The same policy, map and episodes on the grid and flown in MuJoCo."""
    _same_episodes(grid, physics)
    if grid.policy_name != physics.policy_name:
        raise ValueError(f"policies {grid.policy_name!r} and {physics.policy_name!r} compared")
    s = physics.summary()
    cells = {
        "episodes": int(physics.landed.size),
        "grid landing": _pct(grid.landing_ratio),
        "mujoco landing": _pct(physics.landing_ratio),
        "grid coverage": _pct(grid.coverage_ratio),
        "mujoco coverage": _pct(physics.coverage_ratio),
        "J/action": f"{s['energy_per_action_j']:.0f}",
        "nfz viol.": s["nfz_violations"],
    }
    values = {grid.backend: _numbers(grid), physics.backend: _numbers(physics)}
    conditions = {grid.backend: grid.conditions, physics.backend: physics.conditions}
    return _row(grid, cells, values, conditions, backend=f"{grid.backend} vs {physics.backend}")


def wind_speed(result) -> float:
    """The steady wind a MuJoCo result was flown in (0 on the grid)."""
    physics = result.conditions.get("physics_config") or {}
    env_kwargs = result.conditions.get("env_kwargs") or {}
    return float(physics.get("wind_speed", env_kwargs.get("wind_speed", 0.0)))


def wind_row(result) -> dict:
    """One policy flown in MuJoCo under one wind (the wind sweep)."""
    s = result.summary()
    cells = {
        "wind m/s": f"{wind_speed(result):.1f}",
        "landing": _pct(s["landing_ratio"]),
        "coverage": _pct(s["coverage_ratio"]),
        "J/action": f"{s['energy_per_action_j']:.0f}",
        "crashes": s["crashes"],
        "nfz viol.": s["nfz_violations"],
    }
    return _row(result, cells, _numbers(result), result.conditions)


def weather(result) -> str:
    """The weather a result was flown in, as one cell (``calm``, ``9 m/s N/E/S/W + moderate
    turbulence``): :func:`~cpp_mujoco.review.report_conditions.weather_summary`, the one rule."""
    return weather_summary(result.conditions) or "calm"


RATED_COLUMNS = [
    "map", "policy", "weather", "episodes", "landing", "coverage", "crashes", "nfz viol.",
    "max off-track m",
]  # fmt: skip


def rated_row(result) -> dict:
    """One policy over the protocol in one weather: the no-fly record first."""
    s = result.summary()
    cells = {
        "weather": weather(result),
        "episodes": int(result.landed.size),
        "landing": _pct(s["landing_ratio"]),
        "coverage": _pct(s["coverage_ratio"]),
        "crashes": s["crashes"],
        "nfz viol.": s["nfz_violations"],
        "max off-track m": f"{s['max_track_error_m']:.2f}",
    }
    reasons, counts = np.unique(result.physics["crash_reason"], return_counts=True)
    crashes = {str(r): int(n) for r, n in zip(reasons, counts, strict=True) if r}
    values = {**_numbers(result), "crash_reasons": crashes}
    if "guard_takeovers" in result.physics:  # how often the return guard chose the action
        values["guard_takeovers"] = int(np.sum(result.physics["guard_takeovers"]))
        values["guard_episodes"] = int(np.count_nonzero(result.physics["guard_takeovers"]))
    return _row(result, cells, values, result.conditions)


def paper_row(agent, greedy, beam) -> dict:
    """The paper's comparison on a bundled map: the agent's landing ratio against the paper's,
    its coverage against the safe greedy and beam-search planners; the bar is both met."""
    _same_episodes(agent, greedy, beam)
    paper = paper_landing(agent.grid_map)
    if paper is None:
        raise ValueError(f"map {agent.map_name!r} is not bundled; the paper has no figure for it")
    crashes = int((~agent.landed).sum())
    met = agent.landing_ratio >= paper and agent.coverage_ratio >= greedy.coverage_ratio
    cells = {
        "landing": f"{_pct(agent.landing_ratio)} ({crashes} of {agent.landed.size} crash)",
        "paper landing": _pct(paper),
        "coverage": _pct(agent.coverage_ratio),
        "safe greedy": _pct(greedy.coverage_ratio),
        "beam search": _pct(beam.coverage_ratio),
        "bar met": "yes" if met else "no",
    }
    values = {r.policy_name: _numbers(r) for r in (agent, greedy, beam)}
    values["paper_landing_ratio"] = paper
    return _row(agent, cells, values, agent.conditions)


# ------------------------------------------------------------------------------------- tables
@dataclass
class Table:
    """One results table: rows from the builders above and the columns shown of them."""

    title: str
    columns: list[str]
    rows: list[dict] = field(default_factory=list)

    def render(self, style: str = "plain") -> str:
        return format_table(self.rows, self.columns, style=style)

    def to_dict(self) -> dict:
        """Title, columns, the conditions every row shares, and the rows (cells, map digest,
        policy, backend, raw numbers, and the conditions that differ between rows)."""
        shared, own = split_conditions([json_plain(r.get("conditions") or {}) for r in self.rows])
        rows = []
        for row, conditions in zip(self.rows, own, strict=True):
            entry = json_plain({k: v for k, v in row.items() if k != "conditions"})
            if conditions:
                entry["conditions"] = conditions
            rows.append(entry)
        return {"title": self.title, "columns": self.columns, "conditions": shared, "rows": rows}


def write_tables(path: str | Path, tables: dict[str, Table], command: str | None = None) -> Path:
    """Write tables (name → table) as one JSON file, atomically; ``command``: what flew them."""
    data: dict = {name: table.to_dict() for name, table in tables.items()}
    if command is not None:
        data["command"] = command
    atomic_write_text(path, json.dumps(data, indent=2))
    return Path(path)


def write_rendered(path: str | Path, tables: dict[str, Table], style: str = "plain") -> Path:
    """Write tables as shown (``plain`` or ``markdown``), one after another, atomically."""
    text = "\n\n".join(t.render(style) for t in tables.values()) + "\n"
    atomic_write_text(path, text)
    return Path(path)
