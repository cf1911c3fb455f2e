"""Paper-style figures with matplotlib: maps (Fig. 2 colours), coverage vs budget (Fig. 3),
trajectories drawn over the map (Fig. 2), and the wind sweep of the transfer study.

Figures are standalone ``matplotlib.figure.Figure`` objects saved to files: no pyplot, no global
backend switch, so drawing here never changes the backend of the program that imports it.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle

from cpp_mujoco.grid.coverage import view_cells
from cpp_mujoco.grid.image import COLORS, zone_colors
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.protocol.evaluate import EvaluationResult
from cpp_mujoco.review.results import weather, wind_speed
from cpp_mujoco.util.io import atomic_path
from cpp_mujoco.util.tables import backend_name

BUDGET_LABEL = "movement budget (actions; in MuJoCo: calm-move energy units)"
COVERAGE_LABEL = "coverage ratio (share of target cells)"
LANDING_LABEL = "landing ratio (share of episodes)"
# the path and its ends in colours no map layer uses (red, green, blue, yellow, light grey)
PATH_COLOR, START_COLOR, END_COLOR = "black", "magenta", "cyan"


def series_label(result: EvaluationResult) -> str:
    """A curve's name: policy and backend (``ddqn[A] grid``, ``ddqn[A] MuJoCo``), so the grid
    and the MuJoCo curves of one policy are never two ``ddqn[A]``."""
    return f"{result.policy_name} {backend_name(result.backend)}"


def budgets_text(results: Sequence[EvaluationResult]) -> str:
    """The budgets flown (``budgets 25..75 step 5``), from the episodes themselves."""
    values = sorted({int(b) for r in results for b in np.unique(r.budgets)})
    if len(values) == 1:
        return f"budget {values[0]}"
    steps = set(np.diff(values).tolist())
    step = f" step {steps.pop()}" if len(steps) == 1 else ""
    return f"budgets {values[0]}..{values[-1]}{step}"


def conditions_text(results: Sequence[EvaluationResult]) -> str:
    """The weather each backend flew in and the budgets, for a title (``MuJoCo: 9 m/s N +
    moderate turbulence; grid: calm; budgets 25..75 step 5``)."""
    by_backend: dict[str, set[str]] = {}
    for r in results:
        by_backend.setdefault(backend_name(r.backend), set()).add(weather(r))
    parts = [f"{b}: {', '.join(sorted(w))}" for b, w in by_backend.items()]
    if len(by_backend) > 1 and len({frozenset(w) for w in by_backend.values()}) == 1:
        parts = [", ".join(sorted(next(iter(by_backend.values()))))]  # the same weather
    return "; ".join([*parts, budgets_text(results)])


def save_figure(fig: Figure, path: str | os.PathLike) -> Path:
    """Save atomically: a crash or a full disk never leaves a half-written figure, and a failed
    write is a one-line :class:`~cpp_mujoco.util.io.WriteError`."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, bbox_inches="tight")
    return Path(path)


def result_map(result: EvaluationResult) -> GridMap:
    """The map a result was evaluated on (results before ``grid_map`` existed: by name)."""
    grid_map = getattr(result, "grid_map", None)
    return grid_map if grid_map is not None else load_map(result.map_name)


def draw_map(ax, grid_map: GridMap, seen: np.ndarray | None = None) -> None:
    """Zones in the paper's colours, seen cells lightened, cell grid lines."""
    img = zone_colors(grid_map).astype(np.float32) / 255
    if seen is not None:
        seen = np.asarray(seen, dtype=bool).reshape(grid_map.shape)
        img[seen] = 0.45 * img[seen] + 0.55
    h, w = grid_map.shape
    ax.imshow(img, interpolation="nearest", extent=(-0.5, w - 0.5, h - 0.5, -0.5))
    ax.set_xticks(np.arange(-0.5, w, 1), minor=True)
    ax.set_yticks(np.arange(-0.5, h, 1), minor=True)
    ax.grid(which="minor", color="white", linewidth=0.4)
    ax.tick_params(which="both", length=0, labelbottom=False, labelleft=False)


def map_figure(map_name: str | GridMap, path: str | os.PathLike) -> Path:
    """:func:`map_plot` saved to ``path``."""
    return save_figure(map_plot(map_name), path)


def map_plot(map_name: str | GridMap) -> Figure:
    """The map in the paper's colours, its cell counts and a legend of its colours."""
    grid_map = load_map(map_name)
    fig = Figure(figsize=(4, 4))
    ax = fig.subplots()
    draw_map(ax, grid_map)
    counts = grid_map.counts()
    ax.set_title(
        f"map {grid_map.label}: {counts['landing']} landing, {counts['target']} target, "
        f"{counts['nfz']} no-fly"
        + (f", {counts['obstacle']} obstacle" if counts["obstacle"] else ""),
        fontsize=9,
    )
    map_legend(fig, path=False, ncol=3, obstacles=grid_map.has_obstacles)
    return fig


def draw_trajectory(ax, grid_map: GridMap, cells: np.ndarray, fov_side: int = 3) -> None:
    """One episode: seen cells lightened, arrows along the path, the start a magenta dot, the
    end a cyan square (:func:`map_legend` names them)."""
    cells = cells[cells >= 0]
    fov_cells, valid = view_cells(grid_map, fov_side)  # what obstacles hide stays unseen
    seen = np.zeros(grid_map.landing.size, dtype=bool)
    seen[fov_cells[cells[1:]][valid[cells[1:]]]] = True
    draw_map(ax, grid_map, seen)
    rows, cols = np.divmod(cells, grid_map.shape[1])
    arrow = {"arrowstyle": "->", "color": PATH_COLOR, "lw": 1.2}
    for (r0, c0), (r1, c1) in zip(
        zip(rows[:-1], cols[:-1], strict=True), zip(rows[1:], cols[1:], strict=True), strict=True
    ):
        if (r0, c0) != (r1, c1):
            ax.annotate("", (c1, r1), (c0, r0), arrowprops=arrow)
    ax.add_patch(Rectangle((cols[-1] - 0.4, rows[-1] - 0.4), 0.8, 0.8, fill=False,
                           ec=END_COLOR, lw=2.5, zorder=4))  # fmt: skip
    ax.plot(cols[0], rows[0], "o", ms=9, mfc=START_COLOR, mec="white", mew=1.5, zorder=5)


def map_legend(fig: Figure, path: bool = True, ncol: int = 5, obstacles: bool = False) -> None:
    """A legend below the figure naming every colour drawn: the zones (the obstacles' with
    ``obstacles``) and, with ``path``, the seen cells, the path, its start and its end."""

    def zone(name: str, label: str) -> Patch:
        return Patch(fc=np.array(COLORS[name]) / 255, ec="0.5", label=label)

    handles = [
        zone("empty", "empty"),
        zone("target", "target"),
        zone("nfz", "no-fly"),
        zone("yellow", "target in no-fly"),
        zone("landing", "landing"),
    ]
    if obstacles:
        handles += [zone("building", "building"), zone("low obstacle", "low obstacle")]
    if path:
        seen = 0.45 * np.array(COLORS["target"]) / 255 + 0.55
        handles += [
            Patch(fc=seen, ec="0.5", label="seen (lightened)"),
            Line2D([], [], color=PATH_COLOR, marker=">", lw=1.2, label="path"),
            Line2D([], [], ls="", marker="o", ms=9, mfc=START_COLOR, mec="0.5", label="start"),
            Line2D(
                [], [], ls="", marker="s", ms=9, mfc="none", mec=END_COLOR, mew=2.5, label="end"
            ),  # fmt: skip
        ]
    place = {"loc": "lower center", "bbox_to_anchor": (0.5, 0.0 if path else -0.08)}
    if fig.get_layout_engine() is not None:  # constrained: the layout makes room below
        place = {"loc": "outside lower center"}
    fig.legend(handles=handles, ncol=ncol, fontsize=8, frameon=False, **place)


def trajectories_figure(
    result: EvaluationResult,
    path: str | os.PathLike,
    budgets: Sequence[int] | None = None,
    start: tuple[int, int] | None = None,
) -> Path:
    """:func:`trajectories_plot` saved to ``path``."""
    return save_figure(trajectories_plot(result, budgets, start), path)


def trajectories_plot(
    result: EvaluationResult,
    budgets: Sequence[int] | None = None,
    start: tuple[int, int] | None = None,
) -> Figure:
    """The paper's Fig. 2: one start, three budgets (default: low, middle, high)."""
    grid_map = result_map(result)
    available = np.unique(result.budgets)
    if budgets is None:
        budgets = [int(available[0]), int(available[len(available) // 2]), int(available[-1])]
    if start is None:
        start = tuple(int(v) for v in result.starts[0])
    fig = Figure(figsize=(4 * len(budgets), 4.2))
    axes = fig.subplots(1, len(budgets))
    for ax, budget in zip(np.atleast_1d(axes), budgets, strict=True):
        sel = np.flatnonzero((result.budgets == budget) & (result.starts == start).all(axis=1))
        if sel.size == 0:
            raise ValueError(f"no episode with start {start} and budget {budget}")
        i = int(sel[0])
        fov_side = int(result.conditions.get("fov_side", 3))
        draw_trajectory(ax, grid_map, result.trajectories[i], fov_side)
        outcome = "landed" if result.landed[i] else "crashed"
        ax.set_title(
            f"{series_label(result)}, map {result.map_name}, budget {budget}\n"
            f"coverage {result.coverage[i]:.0%}, {result.steps[i]} steps, {outcome}",
            fontsize=9,
        )
    fig.suptitle(f"start {start}; {conditions_text([result])}", fontsize=9)
    map_legend(fig, ncol=9 if len(budgets) > 1 else 5, obstacles=grid_map.has_obstacles)
    return fig


def coverage_figure(results: Sequence[EvaluationResult], path: str | os.PathLike) -> Path:
    """The paper's Fig. 3 (:func:`coverage_plot`) saved to ``path``."""
    return save_figure(coverage_plot(results), path)


def coverage_plot(results: Sequence[EvaluationResult]) -> Figure:
    """Mean coverage ratio per budget, one line per policy and backend, with the bound; the
    title names the map, the weather of each backend and the budgets. A policy keeps one colour;
    the grid is drawn dashed with dots on top of MuJoCo's wide line with hollow squares, so
    where the two coincide both stay visible."""
    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    colors = {}
    for result in results:
        table = result.per_budget
        color = colors.setdefault(result.policy_name, f"C{len(colors) % 10}")
        style = (
            {"ls": "--", "marker": "o", "ms": 4, "lw": 1.4, "zorder": 4}
            if result.backend == "grid"
            else {"ls": "-", "marker": "s", "ms": 8, "mfc": "none", "lw": 3, "alpha": 0.6}
        )
        ax.plot(
            [r["budget"] for r in table],
            [r["coverage_ratio"] for r in table],
            color=color,
            label=f"{series_label(result)} (land {result.landing_ratio:.1%})",
            **style,
        )
    table = results[0].per_budget
    ax.plot(
        [r["budget"] for r in table],
        [r["upper_bound"] for r in table],
        "k-.",
        lw=1,
        label="upper bound",
    )
    solved = [r for r in table if "optimum" in r]
    if solved:
        o = results[0].summary()["optimum"]
        proven = o["statuses"].get("optimal", 0)
        budgets = [r["budget"] for r in solved]
        ax.plot(budgets, [r["optimum"] for r in solved], "k-", lw=1.5,
                label=f"optimal ({proven}/{o['episodes_known']} proven)")  # fmt: skip
        if proven < o["episodes_known"]:
            ax.plot(budgets, [r["optimum_bound"] for r in solved], "k:", lw=1,
                    label="proven bound")  # fmt: skip
    ax.set_xlabel(BUDGET_LABEL)
    ax.set_ylabel(COVERAGE_LABEL)
    ax.set_ylim(0, 1.05)
    backends = " vs ".join(dict.fromkeys(backend_name(r.backend) for r in results))
    episodes = "/".join(sorted({str(r.landed.size) for r in results}))
    ax.set_title(
        f"map {results[0].map_name} ({backends}, {episodes} episodes per curve)\n"
        f"{conditions_text(results)}",
        fontsize=9,
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def wind_sweep_figure(results: Sequence[EvaluationResult], path: str | os.PathLike) -> Path:
    """:func:`wind_sweep_plot` saved to ``path``."""
    return save_figure(wind_sweep_plot(results), path)


def wind_sweep_plot(results: Sequence[EvaluationResult]) -> Figure:
    """Landing and coverage ratio against the steady wind, one line per map, policy and backend
    (the wind and the weather are read from each result's conditions)."""
    fig = Figure(figsize=(11, 4.4))
    axes = fig.subplots(1, 2)
    keys = dict.fromkeys((r.map_name, r.policy_name, r.backend) for r in results)
    for key in keys:
        entries = sorted(
            (r for r in results if (r.map_name, r.policy_name, r.backend) == key), key=wind_speed
        )
        winds = [wind_speed(r) for r in entries]
        style = ("o" if key[1].startswith("ddqn") else "s") + (":" if "guard" in key[1] else "-")
        label = f"{series_label(entries[0])}, map {key[0]}"
        axes[0].plot(winds, [r.landing_ratio for r in entries], style, label=label)
        axes[1].plot(winds, [r.coverage_ratio for r in entries], style, label=label)
    extras = sorted({weather(r).partition(" + ")[2] for r in results if wind_speed(r)} - {""})
    extra = f"; above 0: + {', '.join(extras)}" if extras else ""
    for ax, name in zip(axes, (LANDING_LABEL, COVERAGE_LABEL), strict=True):
        ax.set_xlabel(f"steady wind (m/s{extra})")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=7, loc="best")
    episodes = sorted({int(r.landed.size) for r in results})
    maps = ", ".join(dict.fromkeys(r.map_name for r in results))
    backends = ", ".join(dict.fromkeys(backend_name(r.backend) for r in results))
    fig.suptitle(
        f"map {maps}, {backends} under wind: {'/'.join(map(str, episodes))} episodes per point, "
        f"{budgets_text(results)}\nthe wind from N, E, S and W, the budgets dealt round-robin "
        "to them",
        fontsize=10,
    )
    return fig
