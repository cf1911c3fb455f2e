"""The ``maps``, ``evaluate``, ``fly`` and ``demo`` subcommands, and the options and checks
every subcommand shares (:mod:`cpp_mujoco.cli` assembles the command line).

Each ``add_*(subparsers)`` adds one parser and sets ``func``; each command imports what it needs
when it runs, so building the parser stays fast.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# the reference planners (cpp_mujoco.planners.PLANNERS, named here for the parser; a test keeps
# them equal); evaluate flies the first three when no policy is named — the wind planners price
# moves with the observed wind and are asked for by name
PLANNER_NAMES = (
    "random", "safe-greedy", "beam-search", "safe-greedy-wind", "beam-search-wind", "optimal",
)  # fmt: skip
DEFAULT_PLANNERS = PLANNER_NAMES[:3]
# Dryden turbulence levels (MIL-F-8785C), the same as physics.air.turbulence.LEVELS; named
# here so that building the parser imports no numerical module (a test keeps them equal)
TURBULENCE_LEVELS = ("none", "light", "moderate", "severe")


def int_at_least(low: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {value}")
        return value

    parse.__name__ = f"integer >= {low}"
    return parse


def out_dir(path: str) -> Path:
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OSError(f"cannot create output folder {out}: {e.strerror}") from e
    return out


def progress_wanted(args) -> bool:
    """Bars only for a person watching: stderr is a terminal and --no-progress is not given."""
    return not getattr(args, "no_progress", False) and sys.stderr.isatty()


def check_output_file(option: str, path: str | None, suffix: str) -> None:
    """An output file option pointing at a folder fails now, not after the mission flew."""
    if path and Path(path).is_dir():
        example = Path(path) / f"out{suffix}"
        raise ValueError(f"{option} {path} is a folder; give a file name such as {example}")


def _check_agent(spec: str) -> None:
    path = Path(spec)
    if path.is_dir():
        hint = next(
            (f" such as {p}" for p in (path / "best.pt", path / "agent.pt") if p.is_file()), ""
        )
        raise ValueError(f"--agent {spec} is a folder; give a checkpoint file{hint}")


def _load_agent(spec: str, grid_map):
    from cpp_mujoco.agent import load_agent

    _check_agent(spec)
    agent = load_agent(spec)
    shape = getattr(agent, "map_shape", grid_map.shape)
    if shape is not None and tuple(shape) != grid_map.shape:  # None: a general agent, any size
        raise ValueError(
            f"agent {spec!r} was trained on {shape[0]}x{shape[1]} maps; map {grid_map.label!r} "
            f"is {grid_map.shape[0]}x{grid_map.shape[1]}"
        )
    return agent


# ---------------------------------------------------------------------------------------- maps
def cmd_maps(args) -> None:
    from cpp_mujoco.map_commands import check_generate_options, cmd_generate

    if check_generate_options(args):
        return cmd_generate(args)
    from cpp_mujoco.maps import bundled_maps, load_map
    from cpp_mujoco.review.plots import map_figure
    from cpp_mujoco.review.results import file_part
    from cpp_mujoco.review.tables import format_table

    grid_maps = [load_map(spec) for spec in args.maps or bundled_maps()]  # all checked first
    out = out_dir(args.out or "out/maps")
    rows = []
    for grid_map in grid_maps:
        path = map_figure(grid_map, out / f"map_{file_part(grid_map.label)}.png")
        rows.append(
            {
                "map": grid_map.label,
                "size": "x".join(map(str, grid_map.shape)),
                **grid_map.counts(),
                "figure": str(path),
            }
        )
    print(format_table(rows, ["map", "size", "landing", "target", "nfz", "figure"]))


# ------------------------------------------------------------------------------------ evaluate
_WEATHER_DEFAULTS = {
    "wind_speed": 0.0,
    "wind_direction": 0.0,
    "gust_std": 0.0,
    "turbulence": "none",
}


def _wind(args) -> dict:
    """The weather options as ``MuJoCo-v0`` keyword arguments (so results record them); on the
    grid, where there is no weather, a weather option is an error rather than silently ignored."""
    weather = {k: getattr(args, k) for k in _WEATHER_DEFAULTS}
    if args.backend != "mujoco":
        given = [k for k, v in weather.items() if v != _WEATHER_DEFAULTS[k]]
        if given:
            flags = ", ".join("--" + k.replace("_", "-") for k in given)
            raise ValueError(f"{flags}: weather needs --backend mujoco (the grid has none)")
        return {}
    return weather


def _ray_runtime(args):
    """The Ray runtime for ``--ray`` (started or connected once for every policy and map), or
    nothing; a wrong combination or a missing Ray is bad input, named before anything runs."""
    from contextlib import nullcontext

    if args.ray_address and not args.ray:
        raise ValueError("--ray-address needs --ray")
    if not args.ray:
        return nullcontext()
    if args.backend != "mujoco":
        raise ValueError("--ray needs --backend mujoco (the grid protocol runs in this process)")
    from cpp_mujoco.protocol.ray_engine import ray_option_error, ray_runtime

    if error := ray_option_error(args):
        raise ValueError(error)
    return ray_runtime(args.ray_address, args.workers)


def cmd_evaluate(args) -> None:
    from cpp_mujoco.evaluate import protocol_budgets
    from cpp_mujoco.maps import bundled_maps, load_map
    from cpp_mujoco.optimum_commands import optimal_options
    from cpp_mujoco.planners import make_planner
    from cpp_mujoco.review.results import run_evaluation

    weather = _wind(args)  # checked before anything is loaded or written
    runtime = _ray_runtime(args)
    if args.grid_wind is not None and not args.map_set:
        raise ValueError(
            "--grid-wind needs --map-set (bundled maps in wind: scripts/wind_sweep.py)"
        )
    if args.map_set or args.first:
        from cpp_mujoco.map_commands import cmd_evaluate_map_set

        if not args.map_set:
            raise ValueError("--first needs --map-set")
        return cmd_evaluate_map_set(args, DEFAULT_PLANNERS, weather, runtime)
    grid_maps = [load_map(spec) for spec in args.map or bundled_maps()]
    for spec in args.agent:
        _check_agent(spec)
    if not args.planner and not args.agent:
        args.planner = list(DEFAULT_PLANNERS)
    policies = [(name, make_planner(name, optimal=optimal_options(args))) for name in args.planner]
    if args.agent:
        from cpp_mujoco.agent import load_agent
        from cpp_mujoco.map_commands import agent_entry

        policies += [
            agent_entry(s, load_agent(s), args.symmetric_q, args.finish_mask) for s in args.agent
        ]
    out = out_dir(args.out)
    extra: dict = {"progress": progress_wanted(args)}
    extra["budgets"] = protocol_budgets(step=args.budget_step)
    extra["optimum"] = args.optimum
    if args.backend == "mujoco":
        extra.update(workers=args.workers, env_kwargs=weather)
        extra["engine"] = "ray" if args.ray else "local"
    with runtime:
        run_evaluation(grid_maps, policies, out, args.backend, **extra)
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

    weather = _wind(args)  # checked before anything is loaded or written
    grid_map = load_map(args.map)
    start = _parse_start(args.start)
    for option, suffix in (("rrd", ".rrd"), ("video", ".mp4"), ("onboard_video", ".mp4")):
        check_output_file("--" + option.replace("_", "-"), getattr(args, option), suffix)
    if args.planner:
        from cpp_mujoco.planners import make_planner

        policy = make_planner(args.planner)
    elif args.agent:
        policy = _load_agent(args.agent, grid_map)
    elif grid_map.bundled:
        policy = _load_agent(grid_map.name, grid_map)
    else:
        raise ValueError(
            f"map {grid_map.label!r} is not a bundled map, so it has no default agent; "
            "give --agent CHECKPOINT or --planner NAME"
        )
    if (args.video or args.onboard_video or args.rrd) and args.backend == "mujoco":
        from cpp_mujoco.review.rendering import configure_gl

        print(f"offscreen rendering with {configure_gl(args.gl)}", file=sys.stderr)
    from cpp_mujoco.mission import fly_mission

    extra = weather
    outcome = fly_mission(
        policy, grid_map, budget=args.budget, start=start, backend=args.backend, seed=args.seed,
        rrd=args.rrd, video=args.video, onboard_video=args.onboard_video,
        progress=progress_wanted(args), **extra,
    )  # fmt: skip
    result = "landed" if outcome.landed else f"CRASHED ({outcome.crash_reason})"
    print(
        f"map {outcome.map}, {outcome.policy}, start {outcome.start}, budget {outcome.budget}: "
        f"{outcome.steps} actions, {result}, coverage {outcome.coverage_ratio:.1%}, return "
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
    from cpp_mujoco.maps import bundled_maps, load_map
    from cpp_mujoco.review.rendering import configure_gl

    grid_maps = [load_map(spec) for spec in args.map or bundled_maps()]
    out = out_dir(args.out)
    print(f"offscreen rendering with {configure_gl()}")
    from cpp_mujoco.demo import run_demo

    run_demo(
        out, grid_maps, budget_step=args.budget_step, workers=args.workers,
        progress=progress_wanted(args),
    )  # fmt: skip


# ------------------------------------------------------------------------------ shared options
def add_progress_option(p) -> None:
    p.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bars (they are shown only when stderr is a terminal)",
    )


def add_wind_options(p) -> None:
    p.add_argument(
        "--wind-speed", type=float, default=0.0, help="mujoco: steady wind, m/s (default: 0)"
    )
    p.add_argument(
        "--wind-direction",
        type=float,
        default=0.0,
        help="mujoco: where the wind blows from, degrees clockwise from north (default: 0)",
    )
    p.add_argument(
        "--gust-std", type=float, default=0.0, help="mujoco: gust strength, m/s (default: 0)"
    )
    p.add_argument(
        "--turbulence", default="none", choices=TURBULENCE_LEVELS,
        help="mujoco: Dryden turbulence (MIL-F-8785C) on top of the wind; docs/turbulence.md "
        "(default: %(default)s)",
    )  # fmt: skip


def add_workers_option(p) -> None:
    p.add_argument(
        "--workers", type=int_at_least(1), default=None,
        help="MuJoCo worker processes (default: all cores)",
    )  # fmt: skip


def add_maps(sub) -> None:
    p = sub.add_parser("maps", help="draw maps as the paper's colour figure and list cell counts")
    p.add_argument("maps", nargs="*", help="bundled names or PNG paths (default: all bundled)")
    p.add_argument("--out", help="folder for the figures (default: out/maps) or --generate's maps")
    from cpp_mujoco.map_commands import add_generate_options

    add_generate_options(p)
    p.set_defaults(func=cmd_maps)


def add_evaluate(sub) -> None:
    p = sub.add_parser("evaluate", help="run the paper's protocol for planners and agents")
    p.add_argument("--map", nargs="+", help="bundled map names or PNG paths (default: all bundled)")
    from cpp_mujoco.map_commands import add_map_set_options

    add_map_set_options(p)
    p.add_argument(
        "--planner", nargs="*", default=[], choices=PLANNER_NAMES,
        help="reference planners (default: all three, when no --agent is given)",
    )  # fmt: skip
    p.add_argument(
        "--agent", nargs="*", default=[],
        help="trained agents: a bundled agent name (A) or a checkpoint file",
    )  # fmt: skip
    p.add_argument(
        "--symmetric-q", action=argparse.BooleanOptionalAction, default=None,
        help="agents act on Q-values averaged over the map's rotations and mirror images (8 "
        "readings a step), or --no-symmetric-q on their own (default: each file's own rule)",
    )  # fmt: skip
    p.add_argument(
        "--finish-mask", action=argparse.BooleanOptionalAction, default=None,
        help="agents do not land while an unseen target can still be reached and left for "
        "home, or --no-finish-mask they may (default: each file's own rule)",
    )  # fmt: skip
    p.add_argument(
        "--backend", default="grid", choices=["grid", "mujoco"],
        help="simulate on the grid or fly in MuJoCo (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--budget-step", type=int_at_least(1), default=1,
        help="every n-th budget of 25..75 (a map set: its size class's), the largest always "
        "included (default: %(default)s, all)",
    )  # fmt: skip
    add_workers_option(p)
    p.add_argument(
        "--ray", action="store_true",
        help="mujoco: fly the episodes as Ray tasks (pip install -e .[ray]); a local Ray runtime "
        "of --workers CPUs unless --ray-address or RAY_ADDRESS names a cluster",
    )  # fmt: skip
    p.add_argument("--ray-address", help="with --ray: the Ray cluster to fly on (HOST:PORT)")
    add_wind_options(p)
    from cpp_mujoco.optimum_commands import add_solver_options

    add_solver_options(p)
    p.add_argument(
        "--grid-wind", type=float, default=None, metavar="SPEED",
        help="grid, with --map-set: the grid's wind option, SPEED m/s in every episode from one "
        "of the four compass directions, with the calibrated gusts (file names carry it)",
    )  # fmt: skip
    p.add_argument(
        "--out", default="out/evaluate", help="folder for JSON and figures (default: %(default)s)"
    )
    add_progress_option(p)
    p.set_defaults(func=cmd_evaluate)


def add_fly(sub) -> None:
    p = sub.add_parser("fly", help="fly one mission; write a Rerun recording and videos")
    p.add_argument("--map", default="A", help="bundled map name or PNG path (default: A)")
    p.add_argument(
        "--agent", help="bundled agent name or checkpoint file (default: a bundled map's agent)"
    )
    p.add_argument("--planner", choices=PLANNER_NAMES, help="fly a reference planner instead")
    p.add_argument(
        "--budget", type=int_at_least(1), default=40, help="movement budget (default: 40)"
    )
    p.add_argument("--start", help="start cell ROW,COL (default: the first landing cell)")
    p.add_argument(
        "--backend", default="mujoco", choices=["mujoco", "grid"],
        help="fly in MuJoCo or step the grid MDP (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--seed", type=int_at_least(0), default=0, help="seed of the wind gusts (default: 0)"
    )
    add_wind_options(p)
    p.add_argument("--rrd", help="write a Rerun recording here (open with: rerun PATH)")
    p.add_argument("--video", help="write the chase camera's MP4 here")
    p.add_argument("--onboard-video", help="write the downward camera's MP4 here")
    p.add_argument(
        "--gl", choices=["egl", "osmesa"], help="offscreen GL (default: egl, else osmesa)"
    )
    add_progress_option(p)
    p.set_defaults(func=cmd_fly)


def add_demo(sub) -> None:
    p = sub.add_parser(
        "demo", help="the README's main job: agents on the grid and in MuJoCo, recordings, videos"
    )
    p.add_argument("--map", nargs="+", help="bundled map names or PNG paths (default: all bundled)")
    p.add_argument("--out", default="out/demo", help="folder for results (default: %(default)s)")
    p.add_argument(
        "--budget-step", type=int_at_least(1), default=10,
        help="MuJoCo protocol: every n-th budget of 25..75, 1 = all (default: %(default)s)",
    )  # fmt: skip
    add_workers_option(p)
    add_progress_option(p)
    p.set_defaults(func=cmd_demo)
