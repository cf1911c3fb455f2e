"""The ``fly`` subcommand: one mission with its Rerun recording and videos."""

from __future__ import annotations

import sys

from cpp_mujoco.cli.options import (
    PLANNER_NAMES,
    add_any_map_option,
    add_cell_pixels_option,
    add_progress_option,
    add_wind_options,
    check_output_file,
    int_at_least,
    load_agent_for,
    progress_wanted,
    weather_options,
)


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

    weather = weather_options(args)  # checked before anything is loaded or written
    grid_map = load_map(args.map, args.cell_pixels)
    start = _parse_start(args.start)
    for option, suffix in (("rrd", ".rrd"), ("video", ".mp4"), ("onboard_video", ".mp4")):
        check_output_file("--" + option.replace("_", "-"), getattr(args, option), suffix)
    if args.planner:
        from cpp_mujoco.planners import make_planner

        policy = make_planner(args.planner)
    elif args.agent:
        policy = load_agent_for(args.agent, grid_map)
    elif grid_map.bundled:
        policy = load_agent_for(grid_map.name, grid_map)
    else:
        raise ValueError(
            f"map {grid_map.label!r} is not a bundled map, so it has no agent of its own; "
            "fly the general agent (--agent general, any map), a checkpoint (--agent FILE) or "
            "a planner (--planner NAME)"
        )
    if (args.video or args.onboard_video or args.rrd) and args.backend == "mujoco":
        from cpp_mujoco.physics.view.rendering import configure_gl

        print(f"offscreen rendering with {configure_gl(args.gl)}", file=sys.stderr)
    from cpp_mujoco.missions.mission import fly_mission

    extra = weather
    outcome = fly_mission(
        policy, grid_map, budget=args.budget, start=start, backend=args.backend, seed=args.seed,
        rrd=args.rrd, video=args.video, onboard_video=args.onboard_video,
        progress=progress_wanted(args), any_map=args.any_map, **extra,
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
    if "rrd" in outcome.files:
        from cpp_mujoco.review.recording_tools import open_command
    for kind, path in outcome.files.items():
        hint = f"   (open with: {open_command(path)})" if kind == "rrd" else ""
        print(f"{kind}: {path}{hint}")


def add_fly(sub) -> None:
    p = sub.add_parser("fly", help="fly one mission; write a Rerun recording and videos")
    p.add_argument("--map", default="A", help="bundled map name or PNG path (default: A)")
    add_cell_pixels_option(p)
    p.add_argument(
        "--agent", help="bundled agent name or checkpoint file (default: a bundled map's agent)"
    )
    p.add_argument("--planner", choices=PLANNER_NAMES, help="fly a reference planner instead")
    add_any_map_option(p)
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
