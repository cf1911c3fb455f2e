"""The ``fly`` command: one mission with its Rerun recording and videos; its parser is in
:mod:`cpp_mujoco.cli.parsers`."""

from __future__ import annotations

import sys

from cpp_mujoco.cli.options import (
    check_agent_file,
    check_output_file,
    parse_start,
    progress_wanted,
    weather_options,
)
from cpp_mujoco.maps import load_map
from cpp_mujoco.missions.mission import fly_mission
from cpp_mujoco.physics.view.rendering import configure_gl
from cpp_mujoco.planners import make_planner
from cpp_mujoco.review.recording_tools import open_command


def load_agent_for(spec: str, grid_map):
    """``--agent SPEC`` for ``grid_map`` (``NAME+value-beam``: agent NAME searching with its
    values): a per-map agent only on a map of its size."""
    from cpp_mujoco.agent.value_beam import load_policy, split_search  # heavy: torch, an agent

    check_agent_file(split_search(spec)[0])
    agent = load_policy(spec)
    shape = getattr(agent, "map_shape", grid_map.shape)
    if shape is not None and tuple(shape) != grid_map.shape:  # None: a general agent, any size
        raise ValueError(
            f"agent {spec!r} was trained on {shape[0]}x{shape[1]} maps; map {grid_map.label!r} "
            f"is {grid_map.shape[0]}x{grid_map.shape[1]}"
        )
    return agent


def cmd_fly(args) -> None:
    weather = weather_options(args)  # checked before anything is loaded or written
    grid_map = load_map(args.map, args.cell_pixels)
    start = parse_start(args.start)
    for option, suffix in (("rrd", ".rrd"), ("video", ".mp4"), ("onboard_video", ".mp4")):
        check_output_file("--" + option.replace("_", "-"), getattr(args, option), suffix)
    if args.planner:
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
        print(f"offscreen rendering with {configure_gl(args.gl)}", file=sys.stderr)
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
    for kind, path in outcome.files.items():
        hint = f"   (open with: {open_command(path)})" if kind == "rrd" else ""
        print(f"{kind}: {path}{hint}")
