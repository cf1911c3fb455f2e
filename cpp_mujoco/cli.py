"""The ``cpp-mujoco`` command: maps, evaluation, the demo and the benchmark (each with --help)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from cpp_mujoco.maps import MapError, bundled_maps

PLANNER_NAMES = ("random", "safe-greedy", "beam-search")


def _out_dir(path: str) -> Path:
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OSError(f"cannot create output folder {out}: {e.strerror}") from e
    return out


# ---------------------------------------------------------------------------------------- maps
def cmd_maps(args) -> None:
    from cpp_mujoco.maps import load_map
    from cpp_mujoco.review.plots import map_figure
    from cpp_mujoco.review.tables import format_table

    out = _out_dir(args.out)
    rows = []
    for name in args.maps or bundled_maps():
        grid_map = load_map(name)
        path = map_figure(grid_map, out / f"map_{grid_map.name}.png")
        rows.append(
            {
                "map": grid_map.name,
                "size": "x".join(map(str, grid_map.shape)),
                **grid_map.counts(),
                "figure": str(path),
            }
        )
    print(format_table(rows, ["map", "size", "landing", "target", "nfz", "figure"]))


# ------------------------------------------------------------------------------------ evaluate
def _policies(args):
    """(name, policy) pairs from --planner and --agent."""
    from cpp_mujoco.planners import make_planner

    chosen = [(name, make_planner(name)) for name in args.planner]
    for spec in args.agent:
        from cpp_mujoco.agent import load_agent

        chosen.append((f"ddqn[{spec}]", load_agent(spec)))
    return chosen


def run_evaluation(maps, policies, out: Path, backend: str = "grid", verbose: bool = True):
    """Evaluate every policy on every map; write JSON and figures; print the summary table."""
    from cpp_mujoco.evaluate import PAPER_LANDING_RATIO, evaluate
    from cpp_mujoco.review.plots import coverage_figure, trajectories_figure
    from cpp_mujoco.review.tables import format_table

    rows, results = [], {}
    for map_name in maps:
        per_map = []
        for name, policy in policies(map_name) if callable(policies) else policies:
            start = time.perf_counter()
            result = evaluate(policy, map_name, backend=backend, policy_name=name)
            seconds = time.perf_counter() - start
            result.to_json(out / f"{backend}_{result.map_name}_{name}.json")
            per_map.append(result)
            paper = PAPER_LANDING_RATIO.get(result.map_name)
            rows.append(
                {
                    "map": result.map_name,
                    "policy": name,
                    "episodes": int(result.landed.size),
                    "landing": f"{result.landing_ratio:.2%}",
                    "coverage": f"{result.coverage_ratio:.2%}",
                    "paper landing": f"{paper:.2%}" if paper else "-",
                    "seconds": f"{seconds:.2f}",
                }
            )
            safe = name.replace("[", "_").replace("]", "").replace("/", "_")
            trajectories_figure(
                result, out / f"{backend}_{result.map_name}_{safe}_trajectories.png"
            )
        coverage_figure(per_map, out / f"{backend}_{per_map[0].map_name}_coverage.png")
        results[map_name] = per_map
    if verbose:
        print(
            format_table(
                rows,
                ["map", "policy", "episodes", "landing", "coverage", "paper landing", "seconds"],
            )
        )
    return results


def cmd_evaluate(args) -> None:
    out = _out_dir(args.out)
    if not args.planner and not args.agent:
        args.planner = list(PLANNER_NAMES)
    run_evaluation(args.map or bundled_maps(), _policies(args), out, backend=args.backend)
    print(f"\nresults and figures: {out}/")


# ---------------------------------------------------------------------------------------- demo
def cmd_demo(args) -> None:
    out = _out_dir(args.out)
    maps = args.map or bundled_maps()
    print(f"Reference planners under the paper's protocol on maps {', '.join(maps)}\n")
    run_evaluation(
        maps,
        [
            (n, __import__("cpp_mujoco.planners", fromlist=["x"]).make_planner(n))
            for n in PLANNER_NAMES
        ],
        out,
    )
    print(f"\nJSON results and figures (coverage vs budget, trajectories) are in {out}/")


# ----------------------------------------------------------------------------------- benchmark
def cmd_benchmark(args) -> None:
    from cpp_mujoco.benchmark import SECTIONS
    from cpp_mujoco.evaluate import atomic_write_text
    from cpp_mujoco.review.tables import format_table

    unknown = set(args.only) - set(SECTIONS)
    if unknown:
        raise ValueError(
            f"unknown benchmark section(s) {sorted(unknown)}; known: {', '.join(SECTIONS)}"
        )
    report = {}
    for name in args.only or SECTIONS:
        print(f"running {name} benchmark ...", file=sys.stderr)
        report[name] = SECTIONS[name]()
    rows = [
        {"section": s, "measure": k, "value": f"{v:,.2f}" if isinstance(v, float) else v}
        for s, section in report.items()
        for k, v in section.items()
    ]
    print(format_table(rows, ["section", "measure", "value"]))
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.json, json.dumps(report, indent=2))
    print(f"\nwritten: {args.json}")


# ---------------------------------------------------------------------------------------- main
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cpp-mujoco",
        description="UAV coverage path planning under power constraints, on a grid and in MuJoCo.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("maps", help="draw maps as the paper's colour figure and list cell counts")
    p.add_argument("maps", nargs="*", help="bundled names or PNG paths (default: all bundled)")
    p.add_argument(
        "--out", default="out/maps", help="folder for the figures (default: %(default)s)"
    )
    p.set_defaults(func=cmd_maps)

    p = sub.add_parser("evaluate", help="run the paper's protocol for planners and agents")
    p.add_argument("--map", nargs="+", help="maps (default: all bundled)")
    p.add_argument(
        "--planner",
        nargs="*",
        default=[],
        choices=PLANNER_NAMES,
        help="reference planners (default: all, when no --agent is given)",
    )
    p.add_argument(
        "--agent",
        nargs="*",
        default=[],
        help="trained agents: a bundled map name (A) or a checkpoint path",
    )
    p.add_argument("--backend", default="grid", choices=["grid"], help="simulation backend")
    p.add_argument("--out", default="out/evaluate", help="folder for JSON and figures")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("demo", help="the README's main job: evaluate on the bundled maps, figures")
    p.add_argument("--map", nargs="+", help="maps (default: all bundled)")
    p.add_argument("--out", default="out/demo", help="folder for results (default: %(default)s)")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("benchmark", help="measure env, planner, training and physics speed")
    p.add_argument("--only", nargs="*", default=[], help="sections to run (default: all)")
    p.add_argument("--json", default="out/benchmark.json", help="where to write the JSON report")
    p.set_defaults(func=cmd_benchmark)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except (MapError, ValueError, OSError) as e:
        print(f"cpp-mujoco {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            f"cpp-mujoco {args.command}: interrupted; files written so far are complete",
            file=sys.stderr,
        )
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
