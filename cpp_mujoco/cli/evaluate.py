"""The ``evaluate`` subcommand: policies flown through the paper's protocol on maps or a map set,
in the grid or in MuJoCo (locally or on Ray), into tables, figures and their JSON.
"""

from __future__ import annotations

import itertools

from cpp_mujoco.cli.maps import add_map_set_options, agent_entry, cmd_evaluate_map_set
from cpp_mujoco.cli.options import (
    DEFAULT_PLANNERS,
    PLANNER_NAMES,
    add_any_map_option,
    add_cell_pixels_option,
    add_progress_option,
    add_rule_option,
    add_solver_options,
    add_wind_options,
    add_workers_option,
    check_agent_file,
    check_rules,
    int_at_least,
    optimal_options,
    out_dir,
    progress_wanted,
    weather_options,
)


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
    from cpp_mujoco.maps import bundled_maps, load_map
    from cpp_mujoco.missions.lineup import run_evaluation
    from cpp_mujoco.planners import make_planner

    weather = weather_options(args)  # checked before anything is loaded or written
    check_rules(args)
    runtime = _ray_runtime(args)
    if args.grid_wind is not None and not args.map_set:
        raise ValueError(
            "--grid-wind needs --map-set (bundled maps in wind: scripts/wind_sweep.py)"
        )
    if args.map_set or args.first:
        if not args.map_set:
            raise ValueError("--first needs --map-set")
        cmd_evaluate_map_set(args, DEFAULT_PLANNERS, weather, runtime)
        return _write_page(args.out)
    grid_maps = [load_map(spec, args.cell_pixels) for spec in args.map or bundled_maps()]
    for spec in args.agent:
        check_agent_file(spec)
    if not args.planner and not args.agent:
        args.planner = list(DEFAULT_PLANNERS)
    policies = [(name, make_planner(name, optimal=optimal_options(args))) for name in args.planner]
    if args.agent:
        from cpp_mujoco.agent import load_agent
        from cpp_mujoco.protocol.policy import check_fits

        agents = [agent_entry(s, load_agent(s), args.rule) for s in args.agent]
        for (_, agent), grid_map in itertools.product(agents, grid_maps):  # before anything flies
            check_fits(agent, grid_map, args.any_map)
        policies += agents
    out = out_dir(args.out)
    extra: dict = {"progress": progress_wanted(args)}
    extra["budget_step"] = args.budget_step  # of each map's size class
    extra["any_map"] = args.any_map
    extra["optimum"] = args.optimum
    if args.backend == "mujoco":
        extra.update(workers=args.workers, env_kwargs=weather)
        extra["engine"] = "ray" if args.ray else "local"
    with runtime:
        run_evaluation(grid_maps, policies, out, args.backend, **extra)
    print(f"\nresults and figures: {out}/")
    _write_page(out)


def _write_page(out) -> None:
    """``index.html`` in the output folder: its results, tables and figures on one page, headed
    by the command that wrote them."""
    from cpp_mujoco.review.report import invocation, write_report

    print(f"the page: {write_report(out, invocation())}")


def add_evaluate(sub) -> None:
    p = sub.add_parser("evaluate", help="run the paper's protocol for planners and agents")
    p.add_argument("--map", nargs="+", help="bundled map names or PNG paths (default: all bundled)")
    add_cell_pixels_option(p)

    add_map_set_options(p)
    p.add_argument(
        "--planner", nargs="*", default=[], choices=PLANNER_NAMES,
        help="reference planners (default: all three, when no --agent is given)",
    )  # fmt: skip
    p.add_argument(
        "--agent", nargs="*", default=[],
        help="trained agents: a bundled agent name (A) or a checkpoint file",
    )  # fmt: skip
    add_rule_option(p)
    add_any_map_option(p)
    p.add_argument(
        "--backend", default="grid", choices=["grid", "mujoco"],
        help="simulate on the grid or fly in MuJoCo (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--budget-step", type=int_at_least(1), default=1,
        help="every n-th budget of each map's size class (16x16: 25..75, 32x32: 50..150), the "
        "largest always included (default: %(default)s, all)",
    )  # fmt: skip
    add_workers_option(p)
    p.add_argument(
        "--ray", action="store_true",
        help="mujoco: fly the episodes as Ray tasks (pip install -e .[ray]); a local Ray runtime "
        "of --workers CPUs unless --ray-address or RAY_ADDRESS names a cluster",
    )  # fmt: skip
    p.add_argument("--ray-address", help="with --ray: the Ray cluster to fly on (HOST:PORT)")
    add_wind_options(p)

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
