"""The ``demo`` subcommand: the paper's protocol, its transfer to physics and one mission, on one
page."""

from __future__ import annotations

from cpp_mujoco.cli.options import (
    add_progress_option,
    add_workers_option,
    int_at_least,
    out_dir,
    progress_wanted,
)


def cmd_demo(args) -> None:
    from cpp_mujoco.maps import bundled_maps, load_map
    from cpp_mujoco.physics.view.rendering import configure_gl

    grid_maps = [load_map(spec) for spec in args.map or bundled_maps()]
    out = out_dir(args.out)
    print(f"offscreen rendering with {configure_gl()}")
    from cpp_mujoco.missions.demo import run_demo

    run_demo(
        out, grid_maps, budget_step=args.budget_step, workers=args.workers,
        progress=progress_wanted(args),
    )  # fmt: skip


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
