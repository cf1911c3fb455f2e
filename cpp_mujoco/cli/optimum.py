"""The ``optimum`` command: solve the protocol's best missions into the cache; and the exact
planner's options as ``evaluate`` passes them on. Its parser is in :mod:`cpp_mujoco.cli.parsers`.
"""

from __future__ import annotations

from cpp_mujoco.cli.options import DEFAULT_CACHE, progress_wanted
from cpp_mujoco.map_sets.size_classes import map_size, size_config
from cpp_mujoco.maps import bundled_maps, load_map
from cpp_mujoco.planners.optimal import close_gaps, solve_episodes
from cpp_mujoco.planners.optimal_search import SearchOptions
from cpp_mujoco.planners.optimal_solver import SolverOptions
from cpp_mujoco.protocol.evaluate import protocol_budgets, protocol_episodes
from cpp_mujoco.protocol.optimum import default_folder
from cpp_mujoco.protocol.optimum_cache import OptimumCache
from cpp_mujoco.review.optimum_table import optimum_summary


def optimal_options(args) -> dict:
    """``make_planner("optimal", optimal=...)``'s keyword arguments from the command line."""
    options = SolverOptions(
        time_limit_s=args.time_limit,
        workers=args.solver_workers,
        solver=args.solver,
        memory=args.memory,
    )
    return {"options": options, "cache_folder": optimum_folder(args), "jobs": args.jobs}


def optimum_folder(args) -> str:
    """``--optimum``, else the committed cache wherever the package runs from."""
    return args.optimum or str(default_folder() or DEFAULT_CACHE)


def cmd_optimum(args) -> None:
    grid_maps = [load_map(spec) for spec in args.map or bundled_maps()]
    kwargs = optimal_options(args)
    folder = kwargs["cache_folder"]
    caches = [OptimumCache(folder, m) for m in grid_maps]  # a bad file fails before solving
    for grid_map, cache in zip(grid_maps, caches, strict=True):
        config = size_config(map_size(grid_map.shape))  # the map's size class
        budgets = protocol_budgets(config, args.budget_step)
        starts, per_episode = protocol_episodes(grid_map, budgets)
        if args.first:
            starts, per_episode = starts[: args.first], per_episode[: args.first]
        if args.close_gaps:
            entries = close_gaps(
                grid_map, starts, per_episode, SearchOptions(time_limit_s=args.time_limit), cache,
                progress=progress_wanted(args),
            )  # fmt: skip
        else:
            entries = solve_episodes(
                grid_map, starts, per_episode, kwargs["options"], cache, args.jobs,
                progress=progress_wanted(args),
            )  # fmt: skip
        print(optimum_summary(grid_map, entries, cache.path))
