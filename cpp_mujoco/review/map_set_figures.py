"""Figures of map-set results (:mod:`cpp_mujoco.protocol.map_sets`): how each policy did on each map
of a held-out set, and what it did on a few of them.

Both are drawn from a result's JSON dict (``MapSetResult.to_dict()``, or the file ``evaluate
--map-set`` wrote), never from the live objects, so a run made elsewhere (a GPU machine) is
plotted here exactly as one made here, and a figure shows only what its file records. Every
figure names the set (name, version, maps used of its count), the backend (and MuJoCo's
weather), the budgets and the policies: a figure without them is an ambiguous number.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from cpp_mujoco.map_sets.generator import GENERATOR_VERSION, generate_from_seed
from cpp_mujoco.maps import GridMap
from cpp_mujoco.review.plots import COVERAGE_LABEL, draw_trajectory, map_legend, save_figure
from cpp_mujoco.review.results import weather
from cpp_mujoco.util.tables import backend_name

MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
TICK_LABELS_UP_TO = 40  # maps on the x axis named one by one; beyond, only their rank


@dataclass(frozen=True)
class MapSetFigureOptions:
    """What the figures show: the policy the maps are sorted by (default: each result's first),
    and the maps whose example episodes are drawn (default: the first ``count``)."""

    reference: str | None = None
    maps: tuple[str, ...] = ()
    count: int = 4


# ------------------------------------------------------------------------------- reading
def load_map_set_result(path: str | os.PathLike) -> dict:
    """A map-set result JSON; anything else (a single-map result) is a one-line error."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ValueError(f"cannot read map-set result {path}: {e}") from None
    if not isinstance(data, dict) or not {"map_set", "rows", "budgets"} <= data.keys():
        raise ValueError(f"{path} is not a map-set result (evaluate --map-set writes those)")
    return data


def merge_map_set_results(results: Sequence[dict]) -> dict:
    """Results of one set flown in separate runs (the planners here, an agent later or on
    another machine) as one: they must name the same set, maps (by digest), backend and budgets,
    and no policy twice. Each row keeps all of its conditions (its run's shared ones included)."""
    first = results[0]
    maps = [(r["map"], r["map_digest"]) for r in first["rows"]]
    rows, summaries = [], []
    for data in results:
        if _merge_key(data) != _merge_key(first):
            raise ValueError(
                f"cannot merge results of {set_label(data)}, {run_label(data)} with "
                f"{set_label(first)}, {run_label(first)}"
            )
        for name in policies(data):
            own = [(r["map"], r["map_digest"]) for r in data["rows"] if r["policy"] == name]
            if sorted(own) != sorted(set(maps)):
                raise ValueError(f"policy {name!r} flew other maps than the first result's")
            if any(name == r["policy"] for r in rows):
                raise ValueError(f"policy {name!r} is in two of the results")
        shared = data.get("conditions") or {}
        rows += [{**r, "conditions": {**shared, **r.get("conditions", {})}} for r in data["rows"]]
        summaries += data.get("policies", [])
    return {**first, "policies": summaries, "conditions": {}, "rows": rows}


def policies(data: dict) -> list[str]:
    return list(dict.fromkeys(r["policy"] for r in data["rows"]))


def map_names(data: dict) -> list[str]:
    return list(dict.fromkeys(r["map"] for r in data["rows"]))


def per_map(data: dict, field: str) -> dict[str, np.ndarray]:
    """Policy → ``field`` of each map, in the set's map order (NaN where a row is missing)."""
    maps = {name: i for i, name in enumerate(map_names(data))}
    out = {p: np.full(len(maps), np.nan) for p in policies(data)}
    for r in data["rows"]:
        out[r["policy"]][maps[r["map"]]] = r[field]
    return out


# ------------------------------------------------------------------------------- labels
def set_label(data: dict) -> str:
    """``heldout16-v1 v1, 16x16, 2 of 100 maps`` — the set, and how much of it was used."""
    s = data["map_set"]
    return (
        f"{s['name']} v{s['version']}, {s['size']}x{s['size']}, "
        f"{s['evaluated']} of {s['count']} maps (seeds {s['first_seed']}.., generator "
        f"v{s['generator_version']})"
    )


def _merge_key(data: dict) -> tuple:
    """What results must share to be one: the set, the backend, the budgets and the air."""
    return data["map_set"], data["backend"], data["budgets"], grid_wind(data)


def grid_wind(data: dict) -> dict | None:
    """The grid's wind option a map-set result was flown in (``evaluate --grid-wind``; None:
    calm air), from the conditions its rows share or else its first row's."""
    conditions = data.get("conditions") or {}
    if "grid_config" not in conditions and data.get("rows"):
        conditions = data["rows"][0].get("conditions") or {}
    return (conditions.get("grid_config") or {}).get("wind")


def run_label(data: dict) -> str:
    """``grid, budgets 25..75 step 25``, ``grid (wind 9 m/s, N/E/S/W), budgets ...`` or
    ``MuJoCo (9 m/s N), budgets ...``."""
    b = data["budgets"]
    budgets = f"budgets {b['min']}..{b['max']} step {b['step']}"
    backend = backend_name(data["backend"])
    if data["backend"] == "mujoco":
        backend += f" ({weather(SimpleNamespace(conditions=data.get('conditions') or {}))})"
    elif (wind := grid_wind(data)) is not None:
        lo, hi = wind["min_speed"], wind["max_speed"]
        speed = f"{lo:g}" if lo == hi else f"{lo:g}..{hi:g}"
        calm = f", {wind['calm_fraction']:.0%} calm" if wind["calm_fraction"] else ""
        backend += f" (wind {speed} m/s, {'/'.join(wind['directions'])}{calm})"
    return f"{backend}, {budgets}"


def policy_label(name: str) -> str:
    """A policy as a legend names it: an agent's checkpoint by its last two path parts."""
    if name.startswith("ddqn[") and "/" in name:
        return "ddqn[" + "/".join(name[5:-1].rstrip("/").split("/")[-2:]) + "]"
    return name


# ------------------------------------------------------------------------ per-map coverage
def coverage_plot(results: Sequence[dict], reference: str | None = None) -> Figure:
    """Per-map coverage, one panel per result (smallest maps first): the maps sorted by the
    reference policy's coverage, one marker series per policy, a marker filled only where the
    policy landed in every episode of that map; dashed lines are the means over the maps."""
    results = sorted(results, key=lambda d: d["map_set"]["size"])
    most = max(len(policies(d)) for d in results)
    legend_height = 0.3 * (most + 1)
    fig = Figure(figsize=(6.5 * len(results), 4.4 + legend_height), layout="constrained")
    axes = fig.subplots(
        2, len(results), squeeze=False, height_ratios=[4.4, legend_height]
    )  # the legends below the panels, where they hide no marker
    for j, data in enumerate(results):
        _coverage_panel(axes[0, j], axes[1, j], data, reference)
    names = ", ".join(dict.fromkeys(policy_label(p) for d in results for p in policies(d)))
    fig.suptitle(
        f"per-map coverage on held-out map sets — policies: {names}\n"
        "filled: landed in 100 % of the map's episodes; hollow: at least one did not land",
        fontsize=9,
    )
    return fig


def _coverage_panel(ax, legend_ax, data: dict, reference: str | None) -> None:
    names = policies(data)
    ref = reference or names[0]
    if ref not in names:
        raise ValueError(f"policy {ref!r} is not in {data['map_set']['name']}: {names}")
    coverage, landing = per_map(data, "coverage_ratio"), per_map(data, "landing_ratio")
    order = np.lexsort((np.arange(len(coverage[ref])), coverage[ref]))
    x = np.arange(1, len(order) + 1)
    colors = [f"C{i % 10}" for i in range(len(names))]
    for i, name in enumerate(names):
        y, landed = coverage[name][order], landing[name][order] >= 1.0
        faces = [colors[i] if full else "none" for full in landed]
        ax.scatter(
            x, y, s=30 if len(x) <= TICK_LABELS_UP_TO else 14, marker=MARKERS[i % len(MARKERS)],
            facecolors=faces, edgecolors=colors[i], linewidths=1.0, zorder=3,
            label=f"{policy_label(name)}: mean coverage {np.nanmean(y):.1%}, mean landing "
            f"{np.nanmean(landing[name]):.1%}, all landed on {int(landed.sum())}/{len(x)} maps",
        )  # fmt: skip
        ax.axhline(np.nanmean(y), color=colors[i], ls="--", lw=0.8, alpha=0.7)
    if len(x) <= TICK_LABELS_UP_TO:
        labels = [map_names(data)[j] for j in order]
        ax.set_xticks(x, labels, rotation=90, fontsize=6)
    ax.set_xlabel(f"map, sorted by {policy_label(ref)}'s coverage ({len(x)} maps)")
    ax.set_ylabel(COVERAGE_LABEL)
    ax.set_ylim(0, 1.05)
    ax.grid(alpha=0.3)
    handles, _ = ax.get_legend_handles_labels()
    hollow = Line2D([], [], ls="none", marker="o", mfc="none", mec="grey")
    hollow.set_label("hollow: landed in < 100 % of the map's episodes; dashed: the means")
    legend_ax.set_axis_off()
    legend_ax.legend(handles=[*handles, hollow], fontsize=7, loc="upper center", frameon=False)
    ax.set_title(f"{set_label(data)}\n{run_label(data)}", fontsize=8)


# ---------------------------------------------------------------------------- trajectories
def result_grid_map(data: dict, row: dict, grid_maps: Mapping[str, GridMap] | None) -> GridMap:
    """A row's map: the one given, else regenerated from its seed and checked by its digest."""
    if grid_maps and row["map"] in grid_maps:
        return grid_maps[row["map"]]

    options = data["map_set"].get("generator_options", {})  # a family's options (doors, city)
    grid_map = generate_from_seed(int(row["seed"]), int(data["map_set"]["size"]), **options)
    if grid_map.digest != row["map_digest"]:
        raise ValueError(
            f"map {row['map']} regenerates with digest {grid_map.digest}, the result's is "
            f"{row['map_digest']} (result: generator v{data['map_set']['generator_version']}, "
            f"this one: v{GENERATOR_VERSION})"
        )
    return grid_map


def trajectories_plot(
    data: dict,
    maps: Sequence[str] = (),
    count: int = 4,
    grid_maps: Mapping[str, GridMap] | None = None,
) -> Figure:
    """One row per map (``maps``, else the set's first ``count``), one column per policy: the
    map with the cells the row's example episode visited (seen cells lightened, start magenta,
    end cyan, a legend naming every colour) — what each policy did on a map it may never have
    seen."""
    names, known = policies(data), map_names(data)
    chosen = list(maps) or known[:count]
    if unknown := [m for m in chosen if m not in known]:
        raise ValueError(f"maps {unknown} are not in this result; it has {known[:5]}..")
    rows = {(r["map"], r["policy"]): r for r in data["rows"]}
    if any("example" not in r for r in data["rows"]):
        raise ValueError(
            "this result has no example episodes (written before evaluate --map-set kept "
            "them); run it again to draw trajectories"
        )
    fov = int((data.get("conditions") or {}).get("fov_side", 3))
    fig = Figure(figsize=(3.2 * len(names), 3.4 * len(chosen) + 0.6), layout="constrained")
    axes = fig.subplots(len(chosen), len(names), squeeze=False)
    for i, map_name in enumerate(chosen):
        for j, policy in enumerate(names):
            ax, row = axes[i, j], rows.get((map_name, policy))
            if row is None:
                ax.set_axis_off()
                continue
            ex = row["example"]
            draw_trajectory(ax, result_grid_map(data, row, grid_maps), np.array(ex["cells"]), fov)
            end = "landed" if ex["landed"] else "NOT landed"
            ax.set_title(
                f"{policy_label(policy)}\ncoverage {ex['coverage_ratio']:.0%}, "
                f"{ex['steps']} actions, {end}",
                fontsize=8,
            )
            if j == 0:
                start = tuple(ex["start"])
                ax.set_ylabel(f"{map_name}\nstart {start}, budget {ex['budget']}", fontsize=8)
    fig.suptitle(
        f"{set_label(data)}\n{run_label(data)}; one episode per map and policy: the map's first "
        f"landing cell, budget {data['rows'][0]['example']['budget']}",
        fontsize=9,
    )
    map_legend(fig, ncol=5)
    return fig


# ---------------------------------------------------------------------------------- files
def write_map_set_figures(
    results: Mapping[str, dict],
    out: str | os.PathLike,
    grid_maps: Mapping[str, GridMap] | None = None,
    options: MapSetFigureOptions | None = None,
) -> list[Path]:
    """``results`` (file stem → result dict): one per-map coverage figure of them all (a panel
    per set), and each one's trajectories when its rows keep example episodes."""
    options = options or MapSetFigureOptions()
    out = Path(out)
    stems = list(results)
    paths = [
        save_figure(
            coverage_plot(list(results.values()), options.reference),
            out / f"{'+'.join(stems)}_coverage.png",
        )
    ]
    known = {m for data in results.values() for m in map_names(data)}
    if unknown := [m for m in options.maps if m not in known]:
        raise ValueError(f"maps {unknown} are in none of the results")
    for stem, data in results.items():
        if all("example" in r for r in data["rows"]):
            maps = [m for m in options.maps if m in map_names(data)]
            if options.maps and not maps:
                continue  # the maps asked for are another set's
            fig = trajectories_plot(data, maps, options.count, grid_maps)
            paths.append(save_figure(fig, out / f"{stem}_trajectories.png"))
    return paths
