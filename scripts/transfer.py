"""Grid → MuJoCo transfer results: the grid-vs-physics table per map and the wind sweep.

Regenerates everything the README's transfer section shows:
    python scripts/transfer.py                  # full protocol in MuJoCo, sweep every 5th budget
    python scripts/transfer.py --budget-step 5  # quicker: every 5th budget everywhere
Writes out/transfer/{transfer.md, transfer.json, wind_sweep.png, coverage_*.png}.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cpp_mujoco.evaluate import evaluate, protocol_budgets
from cpp_mujoco.maps import bundled_maps, load_map
from cpp_mujoco.review.plots import coverage_figure, wind_sweep_figure
from cpp_mujoco.review.results import (
    TRANSFER_COLUMNS,
    WIND_COLUMNS,
    Table,
    demo_policies,
    file_part,
    transfer_row,
    wind_row,
    write_rendered,
    write_tables,
)

WINDS = (0.0, 3.0, 6.0, 9.0)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", nargs="+", default=bundled_maps(), help="names or PNG paths")
    parser.add_argument("--budget-step", type=int, default=1, help="MuJoCo protocol budgets step")
    parser.add_argument("--sweep-step", type=int, default=5, help="wind sweep budgets step")
    parser.add_argument("--gust-std", type=float, default=1.0, help="gusts in the wind sweep")
    parser.add_argument("--workers", type=int, default=None, help="MuJoCo processes")
    parser.add_argument("--out", default="out/transfer", help="output folder")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    progress = sys.stderr.isatty()
    grid_maps = [load_map(m) for m in args.maps]
    transfer = Table("grid vs MuJoCo, the same episodes", TRANSFER_COLUMNS)
    wind = Table("MuJoCo under steady wind and gusts", WIND_COLUMNS)
    sweep = []
    for grid_map in grid_maps:
        map_name = grid_map.label
        name, policy = demo_policies(grid_map)[0]  # the bundled agent where there is one
        budgets = protocol_budgets(step=args.budget_step)
        grid = evaluate(policy, grid_map, budgets=budgets, policy_name=name)
        physics = evaluate(policy, grid_map, backend="mujoco", budgets=budgets,
                           policy_name=name, workers=args.workers, progress=progress)  # fmt: skip
        transfer.rows.append(transfer_row(grid, physics))
        coverage_figure([grid, physics], out / f"coverage_{file_part(map_name)}.png")
        sweep_budgets = protocol_budgets(step=args.sweep_step)
        for speed in WINDS:
            result = evaluate(
                policy, grid_map, backend="mujoco", budgets=sweep_budgets, policy_name=name,
                workers=args.workers, progress=progress,
                env_kwargs={"wind_speed": speed, "gust_std": args.gust_std if speed else 0.0},
            )  # fmt: skip
            sweep.append(result)
            wind.rows.append(wind_row(result))
    print(transfer.render())
    print()
    print(wind.render())
    tables = {"transfer": transfer, "wind": wind}
    write_tables(out / "transfer.json", tables)
    write_rendered(out / "transfer.md", tables, "markdown")
    wind_sweep_figure(sweep, out / "wind_sweep.png", args.gust_std)
    print(f"\nwritten: {out}/transfer.md, transfer.json, wind_sweep.png, coverage_*.png")


if __name__ == "__main__":
    main()
