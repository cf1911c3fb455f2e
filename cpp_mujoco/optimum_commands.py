"""The ``optimum`` subcommand (solve the protocol's best missions into the cache) and the exact
planner's options that ``evaluate`` shares."""

from __future__ import annotations

import argparse
import math

DEFAULT_CACHE = "results/optimum"  # the committed cache of the bundled maps' protocol


def positive_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, got {text}")
    return value


def add_solver_options(p) -> None:
    from cpp_mujoco.commands import int_at_least
    from cpp_mujoco.planners.optimal_solver import SOLVERS

    p.add_argument(
        "--time-limit", type=positive_seconds, default=60.0, metavar="S",
        help="the exact planner's solver time per episode; a mission not proven by then is "
        "kept and labelled so (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--solver-workers", type=int_at_least(1), default=1,
        help="the solver's threads per episode (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--solver", choices=SOLVERS, default=SOLVERS[0],
        help="the exact planner's solver: HiGHS (branch and cut) or OR-Tools CP-SAT "
        "(default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--jobs", type=int_at_least(1), default=1,
        help="episodes solved at once, one process each (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--optimum", default=DEFAULT_CACHE, metavar="DIR",
        help="the solved episodes' cache, one JSON file per map digest: read, and written by "
        "what is solved (default: %(default)s)",
    )  # fmt: skip


def optimal_options(args) -> dict:
    """``make_planner("optimal", optimal=...)``'s keyword arguments from the command line."""
    from cpp_mujoco.planners.optimal_solver import SolverOptions

    options = SolverOptions(
        time_limit_s=args.time_limit, workers=args.solver_workers, solver=args.solver
    )
    return {"options": options, "cache_folder": args.optimum, "jobs": args.jobs}


def cmd_optimum(args) -> None:
    from cpp_mujoco.commands import progress_wanted
    from cpp_mujoco.evaluate import protocol_budgets, protocol_episodes
    from cpp_mujoco.maps import bundled_maps, load_map
    from cpp_mujoco.planners.optimal import solve_episodes
    from cpp_mujoco.planners.optimum_cache import OptimumCache
    from cpp_mujoco.review.optimum_table import optimum_summary

    grid_maps = [load_map(spec) for spec in args.map or bundled_maps()]
    budgets = protocol_budgets(step=args.budget_step)
    kwargs = optimal_options(args)
    caches = [OptimumCache(args.optimum, m) for m in grid_maps]  # a bad file fails before solving
    for grid_map, cache in zip(grid_maps, caches, strict=True):
        starts, per_episode = protocol_episodes(grid_map, budgets)
        if args.first:
            starts, per_episode = starts[: args.first], per_episode[: args.first]
        entries = solve_episodes(
            grid_map, starts, per_episode, kwargs["options"], cache, args.jobs,
            progress=progress_wanted(args),
        )  # fmt: skip
        print(optimum_summary(grid_map, entries, cache.path))


def add_optimum(sub) -> None:
    from cpp_mujoco.commands import add_progress_option, int_at_least

    p = sub.add_parser(
        "optimum", help="solve the protocol's best missions (exact planner) into the cache"
    )
    p.add_argument("--map", nargs="+", help="bundled map names or PNG paths (default: all bundled)")
    p.add_argument(
        "--budget-step", type=int_at_least(1), default=1,
        help="every n-th budget of 25..75, the largest always included (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--first", type=int_at_least(1), help="only the protocol's first N episodes of each map"
    )
    add_solver_options(p)
    add_progress_option(p)
    p.set_defaults(func=cmd_optimum)
