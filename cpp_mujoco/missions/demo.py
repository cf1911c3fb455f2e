"""The README's main job: the bundled agents (or, without them, the planners) on every bundled
map — the paper's protocol on the grid, the same protocol flown in MuJoCo, and one mission per map
recorded for review (Rerun recording, chase and onboard videos), and ``index.html``: the page of
it all (:mod:`cpp_mujoco.review.report`), headed by the command that wrote it.

A map given by path is the map evaluated and named (its label) in every table and file name; it
gets no bundled agent (those were trained on the bundled maps) and no paper figures."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from cpp_mujoco.maps import GridMap, bundled_maps, load_map
from cpp_mujoco.missions.lineup import demo_policies
from cpp_mujoco.missions.mission import fly_mission
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets
from cpp_mujoco.protocol.physics_tasks import chunk_count
from cpp_mujoco.review.plots import coverage_figure, trajectories_figure
from cpp_mujoco.review.recording_tools import open_command
from cpp_mujoco.review.report import invocation, write_report
from cpp_mujoco.review.results import (
    DEMO_GRID_COLUMNS,
    TRANSFER_COLUMNS,
    Table,
    file_part,
    protocol_row,
    transfer_row,
    write_tables,
)
from cpp_mujoco.util.io import atomic_write_text, json_default

__all__ = ["demo_policies", "run_demo"]


def run_demo(
    out: Path,
    maps: list[str | GridMap] | None = None,
    budget_step: int = 10,
    workers: int | None = None,
    progress: bool = False,
    command: str | None = None,
) -> None:
    """``maps``: names, PNG paths or GridMaps (default: the bundled maps). ``command``: the
    command line shown atop ``index.html`` (default: this process's own)."""
    grid_maps = [load_map(m) for m in maps or bundled_maps()]
    budgets = protocol_budgets(step=budget_step)
    grid_table = Table("the paper's protocol on the grid", DEMO_GRID_COLUMNS)
    transfer = Table("grid vs MuJoCo, the same episodes", TRANSFER_COLUMNS)
    missions = []
    started = time.perf_counter()
    for grid_map in grid_maps:
        label = file_part(grid_map.label)
        policies = demo_policies(grid_map)
        # one batch flies in this process: starting worker processes for it costs more than it
        # saves (they import torch and MuJoCo, ≈ 10 s each, for every policy and map)
        episodes = int(grid_map.landing.sum()) * len(budgets)
        for name, policy in policies:
            safe = file_part(name)
            grid = evaluate(policy, grid_map, policy_name=name, progress=progress)
            grid.to_json(out / f"grid_{label}_{safe}.json")
            grid_table.rows.append(protocol_row(grid))
            physics = evaluate(
                policy, grid_map, backend="mujoco", budgets=budgets, policy_name=name,
                workers=workers if chunk_count(episodes) > 1 else 1, progress=progress,
            )  # fmt: skip
            physics.to_json(out / f"mujoco_{label}_{safe}.json")
            grid_same = evaluate(policy, grid_map, budgets=budgets, policy_name=name)
            transfer.rows.append(transfer_row(grid_same, physics))
            coverage_figure([grid_same, physics], out / f"transfer_{label}_{safe}.png")
            trajectories_figure(physics, out / f"mujoco_{label}_{safe}_trajectories.png")
        name, policy = policies[0]
        start = tuple(
            int(v) for v in np.argwhere(grid_map.landing)[len(np.argwhere(grid_map.landing)) // 2]
        )
        stem = f"mission_{label}"
        outcome = fly_mission(
            policy, grid_map, budget=50, start=start, rrd=out / f"{stem}.rrd",
            video=out / f"{stem}_chase.mp4", onboard_video=out / f"{stem}_onboard.mp4",
            progress=progress,
        )  # fmt: skip
        missions.append(outcome)  # what flew it, beside its files, for the page
        atomic_write_text(
            out / f"{stem}.json", json.dumps(outcome.as_dict(), indent=2, default=json_default)
        )
    print("\nThe paper's protocol on the grid (every landing cell × budgets 25..75):")
    print(grid_table.render())
    print(f"\nGrid vs MuJoCo (every landing cell × budgets {budgets[0]}..{budgets[-1]} step "
          f"{budget_step}):")  # fmt: skip
    print(transfer.render())
    write_tables(out / "tables.json", {"grid": grid_table, "transfer": transfer})
    print("\nOne mission per map, flown in MuJoCo (budget 50):")
    for m in missions:
        result = "landed" if m.landed else f"crashed ({m.crash_reason})"
        print(f"  map {m.map} from {m.start}: {m.steps} actions, {result}, coverage "
              f"{m.coverage_ratio:.0%}, {m.energy_used_j / 1000:.1f} kJ")  # fmt: skip
        for kind, path in m.files.items():
            print(f"    {kind:14s} {path}")
    report = write_report(out, command or invocation())
    print(f"\nEverything is in {out}/ ({time.perf_counter() - started:.0f} s); the page: {report}")
    print(f"Open a recording with:  {open_command(missions[0].files['rrd'])}")
