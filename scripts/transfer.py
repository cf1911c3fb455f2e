"""Grid → MuJoCo transfer results: the grid-vs-physics table and the per-action energy.

Regenerates the transfer tables (the wind sweep is ``scripts/wind_sweep.py``):
    python scripts/transfer.py                  # calm: the full protocol
    python scripts/transfer.py --budget-step 5  # quicker transfer table
Writes out/transfer/{transfer.md, transfer.json, coverage_*.png, index.html}.

The energy table flies single actions on an open map (:mod:`cpp_mujoco.physics.action_energy`):
steady wind, and the mean over ``--repeats`` gust histories in ``--turbulence``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cpp_mujoco.maps import bundled_maps, load_map
from cpp_mujoco.missions.lineup import demo_policies
from cpp_mujoco.physics.action_energy import KINDS, action_energy_table
from cpp_mujoco.physics.air.turbulence import LEVELS
from cpp_mujoco.physics.calibration import unit_energy
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets
from cpp_mujoco.protocol.wind import COMPASS_NAMES
from cpp_mujoco.review.plots import coverage_figure
from cpp_mujoco.review.report import script_command, write_report
from cpp_mujoco.review.results import (
    TRANSFER_COLUMNS,
    Table,
    file_part,
    transfer_row,
    write_rendered,
    write_tables,
)

WINDS = (0.0, 3.0, 6.0, 9.0, 12.0)


def energy_table(turbulence: str, repeats: int) -> Table:
    """Battery energy per action in budget units (a calm move's calibrated energy)."""
    config = PhysicsConfig()
    unit = unit_energy(config)
    steady = action_energy_table(config, WINDS)
    gusty = action_energy_table(config, WINDS, turbulence=turbulence, repeats=repeats)
    columns = ["wind m/s", "from", *KINDS]
    if turbulence != "none":
        columns += [f"{k} ({turbulence})" for k in KINDS]
    table = Table(f"energy per action, budget units of {unit:.1f} J", columns)
    for a, b in zip(steady, gusty, strict=True):
        row = {
            "wind m/s": f"{a.wind_speed:g}",
            "from": COMPASS_NAMES[a.wind_direction] if a.wind_speed else "-",
            **{k: f"{a.mean_j[k] / unit:.3f}" if k in a.mean_j else "-" for k in KINDS},
            "backend": "mujoco",
            "values": {"steady": vars(a), turbulence: vars(b), "unit_energy_j": unit},
            "conditions": {"physics_config": {"wind_speed": a.wind_speed,
                                              "wind_direction": a.wind_direction}},
        }  # fmt: skip
        if turbulence != "none":
            for k in KINDS:
                if k in b.mean_j:
                    row[f"{k} ({turbulence})"] = (
                        f"{b.mean_j[k] / unit:.2f} ± {b.std_j[k] / unit:.2f}"
                    )
        table.rows.append(row)
    return table


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", nargs="+", default=bundled_maps(), help="names or PNG paths")
    parser.add_argument("--budget-step", type=int, default=1, help="MuJoCo protocol budgets step")
    parser.add_argument("--turbulence", default="moderate", choices=LEVELS, help="energy table")
    parser.add_argument("--repeats", type=int, default=5, help="gust histories per energy row")
    parser.add_argument("--workers", type=int, default=None, help="MuJoCo processes")
    parser.add_argument("--out", default="out/transfer", help="output folder")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    progress = sys.stderr.isatty()
    energy = energy_table(args.turbulence, args.repeats)
    print(energy.render(), flush=True)
    transfer = Table("grid vs MuJoCo, the same episodes", TRANSFER_COLUMNS)
    for grid_map in map(load_map, args.maps):
        name, policy = demo_policies(grid_map)[0]  # the bundled agent where there is one
        budgets = protocol_budgets(step=args.budget_step)
        grid = evaluate(policy, grid_map, budgets=budgets, policy_name=name)
        physics = evaluate(policy, grid_map, backend="mujoco", budgets=budgets,
                           policy_name=name, workers=args.workers, progress=progress)  # fmt: skip
        transfer.rows.append(transfer_row(grid, physics))
        coverage_figure([grid, physics], out / f"coverage_{file_part(grid_map.label)}.png")
        print(transfer.render().splitlines()[-1], flush=True)
    print(transfer.render())
    tables = {"energy": energy, "transfer": transfer}
    write_tables(out / "transfer.json", tables)
    write_rendered(out / "transfer.md", tables, "markdown")
    write_report(out, script_command(__file__, argv))
    print(f"\nwritten: {out}/transfer.md, transfer.json, coverage_*.png, index.html")


if __name__ == "__main__":
    main()
