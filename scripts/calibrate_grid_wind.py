"""Fly the calibration of the grid's wind option and write ``cpp_mujoco/grid/wind_costs.json``.

    python scripts/calibrate_grid_wind.py [--repeats 10] [--workers 2] [--out PATH]

What each kind of action (upwind, downwind, crosswind move, hover, landing) costs in MuJoCo at
0, 3, 6, 9 and 12 m/s with moderate turbulence, in budget units — see
``cpp_mujoco/physics/wind_costs.py``. The grid MDP reads the file when ``GridConfig.wind`` is set.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from cpp_mujoco.physics.wind_costs import measure_wind_costs
from cpp_mujoco.util.io import atomic_write_text

DEFAULT_OUT = Path(__file__).resolve().parents[1] / "cpp_mujoco" / "grid" / "wind_costs.json"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=10, help="gust histories per direction")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    if args.repeats < 2:
        parser.error("--repeats must be >= 2 (a spread needs two samples)")
    table = measure_wind_costs(repeats=args.repeats, workers=args.workers)
    table["command"] = f"python scripts/calibrate_grid_wind.py --repeats {args.repeats}"
    atomic_write_text(args.out, json.dumps(table, indent=1) + "\n")
    for row in table["speeds"]:
        cells = ", ".join(f"{k} {row['mean'][k]:.2f}±{row['std'][k]:.2f}" for k in table["kinds"])
        print(f"{row['wind_speed']:4.0f} m/s: {cells}; lag-1 corr {row['lag1_correlation']:.2f}")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
