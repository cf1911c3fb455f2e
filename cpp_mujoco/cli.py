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


def run_evaluation(
    maps, policies, out: Path, backend: str = "grid", verbose: bool = True, **evaluate_kwargs
):
    """Evaluate every policy on every map; write JSON and figures; print the summary table."""
    from cpp_mujoco.evaluate import PAPER_LANDING_RATIO, evaluate
    from cpp_mujoco.review.plots import coverage_figure, trajectories_figure
    from cpp_mujoco.review.tables import format_table

    rows, results = [], {}
    for map_name in maps:
        per_map = []
        for name, policy in policies(map_name) if callable(policies) else policies:
            start = time.perf_counter()
            result = evaluate(
                policy, map_name, backend=backend, policy_name=name, **evaluate_kwargs
            )
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


def _wind(args) -> dict:
    return {
        "wind_speed": args.wind_speed,
        "wind_direction": args.wind_direction,
        "gust_std": args.gust_std,
    }


def cmd_evaluate(args) -> None:
    out = _out_dir(args.out)
    if not args.planner and not args.agent:
        args.planner = list(PLANNER_NAMES)
    extra = {}
    if args.backend == "mujoco":
        extra = {"workers": args.workers, "progress": True, "env_kwargs": _wind(args)}
    run_evaluation(args.map or bundled_maps(), _policies(args), out, args.backend, **extra)
    print(f"\nresults and figures: {out}/")


# ----------------------------------------------------------------------------------------- fly
def _parse_start(text: str | None) -> tuple[int, int] | None:
    if text is None:
        return None
    try:
        row, col = (int(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--start must be ROW,COL (e.g. 12,2), got {text!r}") from None
    return row, col


def cmd_fly(args) -> None:
    from cpp_mujoco.maps import load_map

    grid_map = load_map(args.map)
    if args.planner:
        from cpp_mujoco.planners import make_planner

        policy = make_planner(args.planner)
    else:
        from cpp_mujoco.agent import load_agent

        policy = load_agent(args.agent or grid_map.name)
        if policy.map_shape != grid_map.shape:
            raise ValueError(
                f"agent {args.agent!r} was trained on {policy.map_shape[0]}x{policy.map_shape[1]} "
                f"maps; map {grid_map.name!r} is {grid_map.shape[0]}x{grid_map.shape[1]}"
            )
    if (args.video or args.onboard_video or args.rrd) and args.backend == "mujoco":
        from cpp_mujoco.review.rendering import configure_gl

        print(f"offscreen rendering with {configure_gl(args.gl)}", file=sys.stderr)
    from cpp_mujoco.mission import fly_mission

    extra = _wind(args) if args.backend == "mujoco" else {}
    outcome = fly_mission(
        policy,
        grid_map,
        budget=args.budget,
        start=_parse_start(args.start),
        backend=args.backend,
        seed=args.seed,
        rrd=args.rrd,
        video=args.video,
        onboard_video=args.onboard_video,
        **extra,
    )
    result = "landed" if outcome.landed else f"CRASHED ({outcome.crash_reason})"
    print(
        f"map {outcome.map}, start {outcome.start}, budget {outcome.budget}: {outcome.steps} "
        f"actions, {result}, coverage {outcome.coverage_ratio:.1%}, return "
        f"{outcome.total_reward:.1f}"
    )
    if args.backend == "mujoco":
        print(
            f"flight {outcome.flight_time_s:.1f} s, energy {outcome.energy_used_j / 1000:.2f} kJ, "
            f"no-fly violations {outcome.nfz_violations}, wall time {outcome.wall_time_s:.1f} s"
        )
    for kind, path in outcome.files.items():
        hint = f"   (open with: rerun {path})" if kind == "rrd" else ""
        print(f"{kind}: {path}{hint}")


# ---------------------------------------------------------------------------------------- demo
def cmd_demo(args) -> None:
    from cpp_mujoco.review.rendering import configure_gl

    out = _out_dir(args.out)
    print(f"offscreen rendering with {configure_gl()}")
    from cpp_mujoco.demo import run_demo

    run_demo(out, args.map, budget_step=args.budget_step, workers=args.workers)


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
def _add_wind(p) -> None:
    p.add_argument("--wind-speed", type=float, default=0.0, help="mujoco: steady wind, m/s")
    p.add_argument(
        "--wind-direction",
        type=float,
        default=0.0,
        help="mujoco: where the wind blows from, degrees clockwise from north",
    )
    p.add_argument("--gust-std", type=float, default=0.0, help="mujoco: gust strength, m/s")


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
    p.add_argument("--backend", default="grid", choices=["grid", "mujoco"], help="simulation")
    p.add_argument("--workers", type=int, default=None, help="mujoco: processes (default: cores)")
    _add_wind(p)
    p.add_argument("--out", default="out/evaluate", help="folder for JSON and figures")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("fly", help="fly one mission; write a Rerun recording and videos")
    p.add_argument("--map", default="A", help="bundled map name or PNG path (default: A)")
    p.add_argument("--agent", help="bundled agent name or checkpoint path (default: the map's)")
    p.add_argument("--planner", choices=PLANNER_NAMES, help="fly a reference planner instead")
    p.add_argument("--budget", type=int, default=40, help="movement budget (default: 40)")
    p.add_argument("--start", help="start cell ROW,COL (default: the first landing cell)")
    p.add_argument("--backend", default="mujoco", choices=["mujoco", "grid"])
    p.add_argument("--seed", type=int, default=0, help="seed (wind gusts)")
    _add_wind(p)
    p.add_argument("--rrd", help="write a Rerun recording here (open with: rerun PATH)")
    p.add_argument("--video", help="write the chase camera's MP4 here")
    p.add_argument("--onboard-video", help="write the downward camera's MP4 here")
    p.add_argument("--gl", choices=["egl", "osmesa"], help="offscreen GL (default: egl, osmesa)")
    p.set_defaults(func=cmd_fly)

    from cpp_mujoco.agent.cli import add_train_parser

    add_train_parser(sub)

    p = sub.add_parser(
        "demo", help="the README's main job: agents on the grid and in MuJoCo, recordings, videos"
    )
    p.add_argument("--map", nargs="+", help="maps (default: all bundled)")
    p.add_argument("--out", default="out/demo", help="folder for results (default: %(default)s)")
    p.add_argument(
        "--budget-step",
        type=int,
        default=5,
        help="MuJoCo protocol: every n-th budget of 25..75 (1 = the full protocol)",
    )
    p.add_argument("--workers", type=int, default=None, help="MuJoCo processes (default: cores)")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("benchmark", help="measure env, planner, training and physics speed")
    p.add_argument("--only", nargs="*", default=[], help="sections to run (default: all)")
    p.add_argument("--json", default="out/benchmark.json", help="where to write the JSON report")
    p.set_defaults(func=cmd_benchmark)
    return parser


def main(argv: list[str] | None = None) -> int:
    from cpp_mujoco.agent.checkpoint import CheckpointError
    from cpp_mujoco.review.rendering import RenderingError

    args = build_parser().parse_args(argv)
    try:
        if hasattr(args, "func"):
            args.func(args)
        else:
            return args.handler(args)
    except (MapError, ValueError, OSError, CheckpointError, RenderingError) as e:
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
