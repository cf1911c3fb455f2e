"""The ``demo`` command: the paper's protocol, its transfer to physics and one mission, on one
page; its parser is in :mod:`cpp_mujoco.cli.parsers`."""

from __future__ import annotations

from cpp_mujoco.cli.options import out_dir, progress_wanted
from cpp_mujoco.maps import bundled_maps, load_map
from cpp_mujoco.missions.demo import run_demo
from cpp_mujoco.physics.view.rendering import configure_gl


def cmd_demo(args) -> None:
    grid_maps = [load_map(spec) for spec in args.map or bundled_maps()]
    out = out_dir(args.out)
    print(f"offscreen rendering with {configure_gl()}")
    run_demo(
        out, grid_maps, budget_step=args.budget_step, workers=args.workers,
        progress=progress_wanted(args),
    )  # fmt: skip
