"""Flight at the rated wind: no-fly violations, landing and coverage over the whole protocol.

Every bundled agent (on its map) and the safe greedy planner fly every landing cell × budget of
A, B and C in MuJoCo at ``RATED_WIND`` (9 m/s steady + moderate Dryden turbulence), the wind
from N, E, S and W with the budgets dealt round-robin to the four (``cpp_mujoco.protocol.wind``):
    python scripts/rated_wind.py                    # the full protocol
    python scripts/rated_wind.py --budget-step 5    # quicker
    python scripts/rated_wind.py --guard            # also the paper agents and greedy + guard
    python scripts/rated_wind.py --each-direction   # every episode from each of N/E/S/W (4×)
    python scripts/rated_wind.py --maps B --each-direction --agent runs/finetune-B/agent.pt
                                 # a saved agent instead of the bundled policies
    python scripts/rated_wind.py --gust-seed 1      # other gust histories for the same episodes
    python scripts/rated_wind.py --ray --ray-address HEAD:6379   # on a Ray cluster (docs/guide.md)
Writes out/rated_wind/{rated_wind.md, rated_wind.json, index.html}; exits 1 if any no-fly
violation.
"""

from __future__ import annotations

import argparse
import sys
from contextlib import nullcontext
from pathlib import Path

from cpp_mujoco.maps import bundled_maps, load_map
from cpp_mujoco.missions.lineup import select_wind_variants
from cpp_mujoco.protocol.evaluate import protocol_budgets
from cpp_mujoco.protocol.ray_engine import add_ray_options, ray_option_error, ray_runtime
from cpp_mujoco.protocol.wind import RATED_WIND, evaluate_in_winds
from cpp_mujoco.review.report import script_command, write_report
from cpp_mujoco.review.results import (
    RATED_COLUMNS,
    Table,
    rated_row,
    write_rendered,
    write_tables,
)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", nargs="+", default=bundled_maps(), help="names or PNG paths")
    parser.add_argument("--budget-step", type=int, default=1, help="protocol budgets step")
    parser.add_argument("--policies", nargs="+", default=None, help="e.g. safe-greedy")
    parser.add_argument("--workers", type=int, default=None, help="MuJoCo processes")
    add_ray_options(parser)
    parser.add_argument(
        "--guard", action="store_true", help="add '+ guard' runs (return_guard=True)"
    )
    parser.add_argument(
        "--each-direction", action="store_true",
        help="fly every episode from each of N/E/S/W (4x the episodes), not round-robin",
    )  # fmt: skip
    parser.add_argument(
        "--agent", default=None, metavar="PATH",
        help="fly this saved agent (checkpoint or agent file) on every map instead",
    )  # fmt: skip
    parser.add_argument(
        "--gust-seed", type=int, default=0,
        help="k > 0: other gust histories for the same episodes (held-out selection)",
    )  # fmt: skip
    parser.add_argument("--out", default="out/rated_wind", help="output folder")
    args = parser.parse_args(argv)
    command = script_command(__file__, argv)
    if error := ray_option_error(args):
        parser.error(error)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    how = "each of N/E/S/W" if args.each_direction else "N/E/S/W"
    table = Table(f"the rated wind: 9 m/s from {how} + moderate turbulence", RATED_COLUMNS)
    budgets = protocol_budgets(step=args.budget_step)
    grid_maps = [load_map(m) for m in args.maps]  # a bad map fails before any flight
    try:
        variants = (
            agent_variants(grid_maps, args.agent, args.guard)
            if args.agent
            else select_wind_variants(grid_maps, args.policies, args.guard)
        )
    except (ValueError, OSError) as exc:
        parser.error(str(exc))
    if args.gust_seed < 0:
        parser.error(f"--gust-seed must be >= 0, got {args.gust_seed}")
    engine = "ray" if args.ray else "local"
    with ray_runtime(args.ray_address, args.workers) if args.ray else nullcontext():  # once
        for grid_map in grid_maps:
            for name, policy, guard in variants[grid_map.label]:
                result = evaluate_in_winds(
                    policy, grid_map, RATED_WIND["wind_speed"], turbulence=RATED_WIND["turbulence"],
                    budgets=budgets, policy_name=name, workers=args.workers, engine=engine,
                    progress=sys.stderr.isatty(),
                    env_kwargs={
                        **({"return_guard": True} if guard else {}),
                        **({"gust_seed": args.gust_seed} if args.gust_seed else {}),
                    } or None,
                    each_direction=args.each_direction,
                )  # fmt: skip
                table.rows.append(rated_row(result))
                print(table.render().splitlines()[-1], flush=True)
                write_tables(out / "rated_wind.json", {"rated_wind": table}, command)  # every row
                write_rendered(out / "rated_wind.md", {"rated_wind": table}, "markdown")
    print(table.render())
    violations = sum(row["values"]["nfz_violations"] for row in table.rows)
    write_report(out, command)
    print(f"\nwritten: {out}/rated_wind.md, rated_wind.json, index.html; no-fly violations: "
          f"{violations}")  # fmt: skip
    return 1 if violations else 0


def agent_variants(grid_maps, path: str, guard: bool) -> dict[str, list]:
    """The saved agent at ``path`` (and with the guard, if asked) on every map, named by its
    path; it must fit each map (a per-map agent flies its own map only)."""
    from cpp_mujoco.agent import load_agent

    agent, name = load_agent(path), f"ddqn[{path}]"
    runs = [(name, agent, False)] + ([(f"{name} + guard", agent, True)] if guard else [])
    return {g.label: runs for g in grid_maps}


if __name__ == "__main__":
    sys.exit(main())
