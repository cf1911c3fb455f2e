"""The ``evaluate`` command: policies flown through the paper's protocol on maps or a map set,
in the grid or in MuJoCo (locally or on Ray), into tables, figures and their JSON; its parser is
in :mod:`cpp_mujoco.cli.parsers`.
"""

from __future__ import annotations

import itertools
from contextlib import nullcontext

from cpp_mujoco.cli.maps import agent_entry, cmd_evaluate_map_set
from cpp_mujoco.cli.optimum import optimal_options
from cpp_mujoco.cli.options import (
    DEFAULT_PLANNERS,
    check_agent_file,
    check_rules,
    out_dir,
    progress_wanted,
    weather_options,
)
from cpp_mujoco.maps import bundled_maps, load_map
from cpp_mujoco.missions.lineup import run_evaluation
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.policy import check_fits
from cpp_mujoco.protocol.ray_engine import ray_option_error, ray_runtime
from cpp_mujoco.review.report import invocation, write_report


def _ray_runtime(args):
    """The Ray runtime for ``--ray`` (started or connected once for every policy and map), or
    nothing; a wrong combination or a missing Ray is bad input, named before anything runs."""
    if args.ray_address and not args.ray:
        raise ValueError("--ray-address needs --ray")
    if not args.ray:
        return nullcontext()
    if args.backend != "mujoco":
        raise ValueError("--ray needs --backend mujoco (the grid protocol runs in this process)")
    if error := ray_option_error(args):
        raise ValueError(error)
    return ray_runtime(args.ray_address, args.workers)


def cmd_evaluate(args) -> None:
    weather = weather_options(args)  # checked before anything is loaded or written
    check_rules(args)
    runtime = _ray_runtime(args)
    if args.grid_wind is not None and not args.map_set:
        raise ValueError(
            "--grid-wind needs --map-set (bundled maps in wind: scripts/wind_sweep.py)"
        )
    if args.map_set or args.first or args.checkpoint:
        if not args.map_set:
            raise ValueError(("--first" if args.first else "--checkpoint") + " needs --map-set")
        if args.fov_side != 3:
            raise ValueError("--fov-side: a map set is flown with its size class's camera (3)")
        cmd_evaluate_map_set(args, DEFAULT_PLANNERS, weather, runtime)
        return _write_page(args.out)
    grid_maps = [load_map(spec, args.cell_pixels) for spec in args.map or bundled_maps()]
    if not args.planner and not args.agent:
        args.planner = list(DEFAULT_PLANNERS)
    policies = [
        (name, make_planner(name, optimal=optimal_options(args), fov_side=args.fov_side))
        for name in args.planner
    ]
    if args.agent:
        from cpp_mujoco.agent import load_agent  # heavy: torch, only with --agent
        from cpp_mujoco.agent.value_beam import split_search  # heavy: torch, only with --agent

        names = [split_search(spec)[0] for spec in args.agent]  # the agents, search or not
        for name in names:
            check_agent_file(name)
        agents = [
            agent_entry(spec, load_agent(name), args.rule, args.value_beam)
            for spec, name in zip(args.agent, names, strict=True)
        ]
        for (_, agent), grid_map in itertools.product(agents, grid_maps):  # before anything flies
            check_fits(agent, grid_map, args.any_map)
        policies += agents
    out = out_dir(args.out)
    extra: dict = {"progress": progress_wanted(args)}
    extra["budget_step"] = args.budget_step  # of each map's size class
    extra["any_map"] = args.any_map
    extra["optimum"] = args.optimum
    extra["env_kwargs"] = {"fov_side": args.fov_side} if args.fov_side != 3 else {}
    if args.backend == "mujoco":
        extra.update(workers=args.workers, env_kwargs={**extra["env_kwargs"], **(weather or {})})
        extra["engine"] = "ray" if args.ray else "local"
    with runtime:
        run_evaluation(grid_maps, policies, out, args.backend, **extra)
    print(f"\nresults and figures: {out}/")
    _write_page(out)


def _write_page(out) -> None:
    """``index.html`` in the output folder: its results, tables and figures on one page, headed
    by the command that wrote them."""
    print(f"the page: {write_report(out, invocation())}")
