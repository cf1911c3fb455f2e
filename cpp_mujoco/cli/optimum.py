"""The ``optimum`` subcommand: solve the protocol's best missions into the cache."""

from __future__ import annotations

from cpp_mujoco.cli.options import (
    add_progress_option,
    add_solver_options,
    int_at_least,
    optimal_options,
    progress_wanted,
)


def cmd_optimum(args) -> None:
    from cpp_mujoco.map_sets.size_classes import map_size, size_config
    from cpp_mujoco.maps import bundled_maps, load_map
    from cpp_mujoco.planners.optimal import solve_episodes
    from cpp_mujoco.protocol.evaluate import protocol_budgets, protocol_episodes
    from cpp_mujoco.protocol.optimum_cache import OptimumCache
    from cpp_mujoco.review.optimum_table import optimum_summary

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
        entries = solve_episodes(
            grid_map, starts, per_episode, kwargs["options"], cache, args.jobs,
            progress=progress_wanted(args),
        )  # fmt: skip
        print(optimum_summary(grid_map, entries, cache.path))


def add_optimum(sub) -> None:

    p = sub.add_parser(
        "optimum", help="solve the protocol's best missions (exact planner) into the cache"
    )
    p.add_argument("--map", nargs="+", help="bundled map names or PNG paths (default: all bundled)")
    p.add_argument(
        "--budget-step", type=int_at_least(1), default=1,
        help="every n-th budget of each map's size class (16x16: 25..75), the largest always "
        "included (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--first", type=int_at_least(1), help="only the protocol's first N episodes of each map"
    )
    add_solver_options(p)
    add_progress_option(p)
    p.set_defaults(func=cmd_optimum)
