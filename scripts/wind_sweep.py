"""Landing and coverage against the wind, 0–12 m/s, in MuJoCo: the table and the figure.

    python scripts/wind_sweep.py                          # A, B, C; budgets 25, 41, 57, 73, 75
    python scripts/wind_sweep.py --maps C --sweep-step 10 --speeds 0 9
    RAY_ADDRESS=HEAD:6379 python scripts/wind_sweep.py --ray   # on a Ray cluster (docs/guide.md)

Per map: the paper agent, the paper agent + return guard, the wind-robust agent, the safe greedy
planner, the safe greedy planner + guard (``review/results.py``, ``wind_variants``), each at
every speed with the wind from N, E, S and W, the budgets dealt round-robin to the four, in
``--turbulence`` above 0 m/s. Writes out/wind_sweep/{wind_sweep.md, wind_sweep.json,
wind_sweep.png}, rewritten after every point so an interrupted sweep keeps what it flew, and at
the end index.html, the page of all three (``review/report.py``).
"""

from __future__ import annotations

import argparse
import sys
from contextlib import nullcontext
from pathlib import Path

from cpp_mujoco.maps import bundled_maps, load_map
from cpp_mujoco.missions.lineup import select_wind_variants
from cpp_mujoco.physics.air.turbulence import LEVELS
from cpp_mujoco.protocol.evaluate import protocol_budgets, split_conditions
from cpp_mujoco.protocol.ray_engine import add_ray_options, ray_option_error, ray_runtime
from cpp_mujoco.protocol.wind import evaluate_in_winds
from cpp_mujoco.review.plots import wind_sweep_figure
from cpp_mujoco.review.report import script_command, write_report
from cpp_mujoco.review.results import (
    RATED_COLUMNS,
    Table,
    rated_row,
    wind_speed,
    write_rendered,
    write_tables,
)


def pivot(results, speeds) -> Table:
    """One row per map and policy, one "landing / coverage" cell per speed; a row carries the
    backend and the conditions its points share (the speeds are its columns)."""
    columns = ["map", "policy", "episodes per point", *(f"{s:g} m/s" for s in speeds)]
    table = Table("landing / coverage against the steady wind (MuJoCo)", columns)
    for key in dict.fromkeys((r.map_name, r.policy_name) for r in results):
        cells = {wind_speed(r): r for r in results if (r.map_name, r.policy_name) == key}
        shared, _ = split_conditions([r.conditions for r in cells.values()])
        row = {"map": key[0], "policy": key[1], "backend": "mujoco", "conditions": shared}
        row["episodes per point"] = "/".join(sorted({str(r.landed.size) for r in cells.values()}))
        for s in speeds:
            r = cells.get(s)
            row[f"{s:g} m/s"] = f"{r.landing_ratio:.2%} / {r.coverage_ratio:.2%}" if r else ""
        table.rows.append(row)
    return table


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", nargs="+", default=bundled_maps(), help="names or PNG paths")
    parser.add_argument("--speeds", nargs="+", type=float, default=[0.0, 3.0, 6.0, 9.0, 12.0])
    parser.add_argument("--sweep-step", type=int, default=16, help="budgets 25, 25+step, …, 75")
    parser.add_argument("--turbulence", default="moderate", choices=LEVELS, help="above 0 m/s")
    parser.add_argument("--policies", nargs="+", default=None, help="e.g. 'ddqn[A] + guard'")
    parser.add_argument("--workers", type=int, default=None, help="MuJoCo processes")
    add_ray_options(parser)
    parser.add_argument("--out", default="out/wind_sweep", help="output folder")
    args = parser.parse_args(argv)
    command = script_command(__file__, argv)
    if error := ray_option_error(args):
        parser.error(error)
    if any(not 0 <= s <= 12 for s in args.speeds):
        parser.error(f"--speeds must be within 0..12 m/s, got {args.speeds}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    grid_maps = [load_map(m) for m in args.maps]  # a bad map fails before any flight
    try:
        variants = select_wind_variants(grid_maps, args.policies)
    except ValueError as exc:
        parser.error(str(exc))
    budgets = protocol_budgets(step=args.sweep_step)  # 75, the top, always included
    points = Table(f"MuJoCo under wind + {args.turbulence} turbulence", RATED_COLUMNS)
    results = []
    engine = "ray" if args.ray else "local"
    with ray_runtime(args.ray_address, args.workers) if args.ray else nullcontext():  # once
        for grid_map in grid_maps:
            for name, policy, guard in variants[grid_map.label]:
                for speed in args.speeds:
                    result = evaluate_in_winds(
                        policy, grid_map, speed, turbulence=args.turbulence if speed else "none",
                        budgets=budgets, policy_name=name, workers=args.workers, engine=engine,
                        progress=sys.stderr.isatty(),
                        env_kwargs={"return_guard": True} if guard else None,
                    )  # fmt: skip
                    results.append(result)
                    points.rows.append(rated_row(result))
                    print(points.render().splitlines()[-1], flush=True)
                    tables = {"sweep": pivot(results, args.speeds), "points": points}
                    write_tables(out / "wind_sweep.json", tables, command)
                    write_rendered(out / "wind_sweep.md", tables, "markdown")
                    wind_sweep_figure(results, out / "wind_sweep.png")
    print(pivot(results, args.speeds).render())
    report = write_report(out, command)
    print(f"\nwritten: {out}/wind_sweep.md, wind_sweep.json, wind_sweep.png; page: {report}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
