"""The README's main job: the bundled agents (or, without them, the planners) on every bundled
map — the paper's protocol on the grid, the same protocol flown in MuJoCo, and one mission per map
recorded for review (Rerun recording, chase and onboard videos)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from cpp_mujoco.evaluate import PAPER_LANDING_RATIO, atomic_write_text, evaluate
from cpp_mujoco.maps import bundled_maps, load_map
from cpp_mujoco.review.tables import format_table


def demo_policies(map_name: str) -> list[tuple[str, object]]:
    """The bundled agent for the map (if there is one) and the safe greedy planner."""
    from cpp_mujoco.agent import bundled_agents, load_agent
    from cpp_mujoco.planners import SafeGreedyPlanner

    policies: list[tuple[str, object]] = []
    if map_name in bundled_agents():
        policies.append((f"ddqn[{map_name}]", load_agent(map_name)))
    policies.append(("safe-greedy", SafeGreedyPlanner()))
    return policies


def transfer_row(grid, physics) -> dict:
    return {
        "map": grid.map_name,
        "policy": grid.policy_name,
        "episodes": int(physics.landed.size),
        "grid landing": f"{grid.landing_ratio:.2%}",
        "mujoco landing": f"{physics.landing_ratio:.2%}",
        "grid coverage": f"{grid.coverage_ratio:.2%}",
        "mujoco coverage": f"{physics.coverage_ratio:.2%}",
        "J/action": f"{physics.summary()['energy_per_action_j']:.0f}",
        "nfz viol.": physics.summary()["nfz_violations"],
    }


def run_demo(out: Path, maps: list[str] | None = None, budget_step: int = 5, workers=None):
    from cpp_mujoco.mission import fly_mission
    from cpp_mujoco.review.plots import coverage_figure, trajectories_figure

    maps = maps or bundled_maps()
    budgets = list(range(25, 76, budget_step))
    rows, grid_rows, missions = [], [], []
    started = time.perf_counter()
    for map_name in maps:
        grid_map = load_map(map_name)
        for name, policy in demo_policies(map_name):
            safe = name.replace("[", "_").replace("]", "")
            grid = evaluate(policy, grid_map, policy_name=name)
            grid.to_json(out / f"grid_{map_name}_{safe}.json")
            grid_rows.append({
                "map": map_name, "policy": name, "landing": f"{grid.landing_ratio:.2%}",
                "coverage": f"{grid.coverage_ratio:.2%}",
                "paper landing": f"{PAPER_LANDING_RATIO.get(map_name, float('nan')):.2%}",
            })  # fmt: skip
            physics = evaluate(
                policy, grid_map, backend="mujoco", budgets=budgets, policy_name=name,
                workers=workers, progress=True,
            )  # fmt: skip
            physics.to_json(out / f"mujoco_{map_name}_{safe}.json")
            grid_same = evaluate(policy, grid_map, budgets=budgets, policy_name=name)
            rows.append(transfer_row(grid_same, physics))
            coverage_figure([grid_same, physics], out / f"transfer_{map_name}_{safe}.png")
            trajectories_figure(physics, out / f"mujoco_{map_name}_{safe}_trajectories.png")
        name, policy = demo_policies(map_name)[0]
        start = tuple(
            int(v) for v in np.argwhere(grid_map.landing)[len(np.argwhere(grid_map.landing)) // 2]
        )
        stem = f"mission_{map_name}"
        outcome = fly_mission(
            policy, grid_map, budget=50, start=start, rrd=out / f"{stem}.rrd",
            video=out / f"{stem}_chase.mp4", onboard_video=out / f"{stem}_onboard.mp4",
        )  # fmt: skip
        missions.append(outcome)
    print("\nThe paper's protocol on the grid (every landing cell × budgets 25..75):")
    print(format_table(grid_rows, ["map", "policy", "landing", "coverage", "paper landing"]))
    print(f"\nGrid vs MuJoCo (every landing cell × budgets {budgets[0]}..{budgets[-1]} step "
          f"{budget_step}):")  # fmt: skip
    columns = ["map", "policy", "episodes", "grid landing", "mujoco landing", "grid coverage",
               "mujoco coverage", "J/action", "nfz viol."]  # fmt: skip
    print(format_table(rows, columns))
    atomic_write_text(out / "transfer.json", json.dumps(rows, indent=2))
    print("\nOne mission per map, flown in MuJoCo (budget 50):")
    for m in missions:
        result = "landed" if m.landed else f"crashed ({m.crash_reason})"
        print(f"  map {m.map} from {m.start}: {m.steps} actions, {result}, coverage "
              f"{m.coverage_ratio:.0%}, {m.energy_used_j / 1000:.1f} kJ")  # fmt: skip
        for kind, path in m.files.items():
            print(f"    {kind:14s} {path}")
    print(f"\nEverything is in {out}/ ({time.perf_counter() - started:.0f} s).")
    print(f"Open a recording with:  rerun {missions[0].files['rrd']}")
