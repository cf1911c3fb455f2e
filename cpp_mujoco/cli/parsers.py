"""The subcommands' parsers (all but ``train`` and ``train-general``, whose options come from the
training configs: :mod:`~cpp_mujoco.cli.train`, :mod:`~cpp_mujoco.cli.train_general`).

Each ``add_*(subparsers)`` adds one subcommand and sets ``func`` to its command as
``"module:function"``: :func:`cpp_mujoco.cli.main.command` imports that module when the command
runs, so building the parser imports nothing numerical and ``--help`` answers at once. The
commands live in one module each: :mod:`~cpp_mujoco.cli.maps` (``maps draw``, ``maps generate``,
``evaluate --map-set``), :mod:`~cpp_mujoco.cli.evaluate`, :mod:`~cpp_mujoco.cli.fly`,
:mod:`~cpp_mujoco.cli.optimum`, :mod:`~cpp_mujoco.cli.demo`, :mod:`~cpp_mujoco.cli.benchmark`,
:mod:`~cpp_mujoco.cli.site`.
"""

from __future__ import annotations

from cpp_mujoco.cli.options import (
    PLANNER_NAMES,
    add_agent_options,
    add_any_map_option,
    add_budget_step_option,
    add_cell_pixels_option,
    add_fov_side_option,
    add_progress_option,
    add_solver_options,
    add_wind_options,
    add_workers_option,
    int_at_least,
    positive_seconds,
)

DEFAULT_SIZE = 16  # maps generate: the maps' side
# cpp-mujoco benchmark's sections: a module with ``run() -> dict`` each (a flat dict of numbers),
# imported only when its section runs
SECTIONS: dict[str, str] = {
    "grid": "cpp_mujoco.bench.grid",
    "physics": "cpp_mujoco.bench.physics",
    "training": "cpp_mujoco.bench.agent",
    "review": "cpp_mujoco.bench.review",
    "decision": "cpp_mujoco.bench.decision",
}


def add_generate_options(p) -> None:
    p.add_argument("count", type=int_at_least(1), metavar="N", help="how many maps to write")
    p.add_argument("--out", required=True, help="the folder for the PNG maps")
    p.add_argument(
        "--seed", type=int_at_least(0), default=0,
        help="the first map's seed; the n-th map is seed + n (default: %(default)s). "
        "Seeds 1000000..1999999 are the held-out test sets': never train on them",
    )  # fmt: skip
    p.add_argument(
        "--size", type=int_at_least(8), default=DEFAULT_SIZE,
        help="the maps' side, cells (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--family", choices=("paper", "city", "scatter", "field"), default="paper",
        help="paper: blocks of no-fly, target blobs, one landing zone (heldout16-v1, "
        "heldout32-v1); city: buildings on a street grid, low obstacles, landing pads "
        "(city32-v1, city50-v1); scatter: many small blocks, a tiny landing pad, target blobs "
        "(scatter16-v1, scatter32-v1); field: open ground with target patches (field16-v1, "
        "field32-v1) (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--door-wall", type=float, metavar="P",
        help="paper family: the chance each map has a wall across it with one door of 1-2 "
        "cells, as on map C (default: 0, the held-out v1 sets' generator)",
    )  # fmt: skip
    p.add_argument(
        "--overwrite", action="store_true",
        help="write into a non-empty --out (maps of the same name are replaced)",
    )  # fmt: skip


def add_maps_option(p) -> None:
    p.add_argument("--map", nargs="+", help="bundled map names or PNG paths (default: all bundled)")


def add_map_set_options(p) -> None:
    p.add_argument(
        "--map-set", metavar="NAME",
        help="instead of --map: a held-out map set (heldout16-v1, heldout32-v1, doors16-v1: "
        "every map with a wall and one door; city32-v1, city50-v1: buildings that hide "
        "targets; scatter16-v1, scatter32-v1, field16-v1, field32-v1), flown on --backend "
        "with its size class's budgets (16x16: 25..75, 32x32: 50..150, 50x50: 150..250); "
        "writes a JSON and its figures (per-map coverage, example trajectories) into --out",
    )  # fmt: skip
    p.add_argument(
        "--first", type=int_at_least(1), metavar="N",
        help="with --map-set: only its first N maps, for a quick look (results say so)",
    )  # fmt: skip
    p.add_argument(
        "--checkpoint", metavar="FILE",
        help="with --map-set: where the rows are kept as they land, so a stopped flight resumes "
        "(default: <result>.rows.json in --out; removed once the result is written)",
    )  # fmt: skip


def add_maps(sub) -> None:
    p = sub.add_parser(
        "maps", help="draw maps (maps draw, the default), generate random ones (maps generate) or "
        "import one drawn elsewhere (maps import)",
    )  # fmt: skip
    p.set_defaults(func="cpp_mujoco.cli.maps:cmd_draw")
    kinds = p.add_subparsers(
        dest="maps_command", metavar="{draw,generate,import}",
        help="draw (the default), generate or import",
    )  # fmt: skip
    draw = kinds.add_parser("draw", help="draw maps as the paper's colour figure, list cell counts")
    add_maps_option(draw)
    add_cell_pixels_option(draw)
    draw.add_argument("--out", help="folder for the figures (default: out/maps)")
    draw.set_defaults(func="cpp_mujoco.cli.maps:cmd_draw")
    generate = kinds.add_parser("generate", help="write random maps in the paper's style as PNGs")
    add_generate_options(generate)
    generate.set_defaults(func="cpp_mujoco.cli.maps:cmd_generate")
    imported = kinds.add_parser(
        "import", help="write a map drawn elsewhere (a PNG at several pixels per cell or on white, "
        "ASCII text, or a uavSim map) in the map format: one pixel per cell, black empty",
    )  # fmt: skip
    imported.add_argument(
        "source", help="a PNG, or a .txt of rows ('.' empty, L, T, N, Y, G, O, B)"
    )  # fmt: skip
    imported.add_argument("--out", required=True, help="the map PNG to write")
    imported.add_argument(
        "--format", choices=("ours", "uavsim"), default="ours",
        help="the source's colours: ours (R no-fly, G target, B landing, alpha < 255 obstacle) "
        "or uavsim (the lineage's simulator: R no-fly, G obstacle, R+G building, B landing; "
        "targets from --targets or --target-fraction) (default: %(default)s)",
    )  # fmt: skip
    imported.add_argument(
        "--targets", metavar="TARGET.png",
        help="--format uavsim: the targets, any non-zero pixel (those under obstacles dropped)",
    )  # fmt: skip
    imported.add_argument(
        "--target-fraction", type=float, metavar="F",
        help="--format uavsim: draw target patches over this share (0, 1] of the free cells",
    )  # fmt: skip
    imported.add_argument(
        "--seed", type=int_at_least(0), metavar="S",
        help="with --target-fraction: the seed of the drawn targets (default: 0)",
    )  # fmt: skip
    add_cell_pixels_option(imported)
    imported.add_argument("--white-background", action="store_true",
                          help="white pixels are empty cells (a map drawn on white)")  # fmt: skip
    imported.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    imported.set_defaults(func="cpp_mujoco.cli.maps:cmd_import")


def add_evaluate(sub) -> None:
    p = sub.add_parser("evaluate", help="run the paper's protocol for planners and agents")
    add_maps_option(p)
    add_cell_pixels_option(p)
    add_fov_side_option(p)

    add_map_set_options(p)
    p.add_argument(
        "--planner", nargs="*", default=[], choices=PLANNER_NAMES,
        help="reference planners (default: all three, when no --agent is given)",
    )  # fmt: skip
    p.add_argument(
        "--agent", nargs="*", default=[],
        help="trained agents: a bundled agent name (A) or a checkpoint file; NAME+value-beam "
        "searches with its values (general+value-beam: the bundled general policy)",
    )  # fmt: skip
    add_agent_options(p)
    add_any_map_option(p)
    p.add_argument(
        "--backend", default="grid", choices=["grid", "mujoco"],
        help="simulate on the grid or fly in MuJoCo (default: %(default)s)",
    )  # fmt: skip
    add_budget_step_option(p)
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
    p.set_defaults(func="cpp_mujoco.cli.evaluate:cmd_evaluate")


def add_fly(sub) -> None:
    p = sub.add_parser("fly", help="fly one mission; write a Rerun recording and videos")
    p.add_argument("--map", default="A", help="bundled map name or PNG path (default: A)")
    add_cell_pixels_option(p)
    p.add_argument(
        "--agent",
        help="bundled agent name or checkpoint file, NAME+value-beam searching with its values "
        "(default: a bundled map's agent)",
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
    p.set_defaults(func="cpp_mujoco.cli.fly:cmd_fly")


def add_optimum(sub) -> None:
    p = sub.add_parser(
        "optimum", help="solve the protocol's best missions (exact planner) into the cache"
    )
    add_maps_option(p)
    add_budget_step_option(p)
    p.add_argument(
        "--first", type=int_at_least(1), help="only the protocol's first N episodes of each map"
    )
    add_solver_options(p)
    p.add_argument(
        "--close-gaps", action="store_true",
        help="instead of solving, close the cached episodes still open with the exact search "
        "(can a mission see the bound's count? found: optimal; none: the bound drops by one), "
        "--time-limit per question",
    )  # fmt: skip
    add_progress_option(p)
    p.set_defaults(func="cpp_mujoco.cli.optimum:cmd_optimum")


def add_demo(sub) -> None:
    p = sub.add_parser(
        "demo", help="the README's main job: agents on the grid and in MuJoCo, recordings, videos"
    )
    add_maps_option(p)
    p.add_argument("--out", default="out/demo", help="folder for results (default: %(default)s)")
    add_budget_step_option(
        p, 10, "MuJoCo protocol: every n-th budget of 25..75, 1 = all (default: %(default)s)"
    )
    add_workers_option(p)
    add_progress_option(p)
    p.set_defaults(func="cpp_mujoco.cli.demo:cmd_demo")


def add_benchmark(sub) -> None:
    p = sub.add_parser("benchmark", help="measure env, planner, training and physics speed")
    p.add_argument(
        "--only", nargs="*", default=[],
        help=f"sections to run: {' '.join(SECTIONS)} (default: all)",
    )  # fmt: skip
    p.add_argument(
        "--json", default="out/benchmark.json",
        help="where to write the JSON report (default: %(default)s)",
    )  # fmt: skip
    add_progress_option(p)
    p.set_defaults(func="cpp_mujoco.cli.benchmark:cmd_benchmark")


def add_site(sub) -> None:
    """``site grid`` and ``site plan``: a real site's polygons to a map, and to a mission. The
    defaults named in the help are the configs' (:mod:`cpp_mujoco.sites`; a test keeps them
    equal): an option left out is not passed on."""
    p = sub.add_parser(
        "site",
        help="a real site (GeoJSON or KML polygons) to a grid map and to a checked "
        "mission: QGroundControl plan, MAVLink waypoints, flown in MuJoCo (the site extra)",
    )
    p.set_defaults(func="cpp_mujoco.cli.site:cmd_site_plan")  # a sub-command is required
    kinds = p.add_subparsers(
        dest="site_command", metavar="{grid,plan}", required=True,
        help="grid: the site as a map and its georeference; plan: and a checked mission",
    )  # fmt: skip
    grid = kinds.add_parser("grid", help="rasterise the site: the map PNG and its georeference")
    plan = kinds.add_parser(
        "plan", help="plan, export, read back, fly in MuJoCo and check a mission on the site"
    )
    for q in (grid, plan):
        q.add_argument(
            "site",
            help="the site: a GeoJSON (.geojson, .json) or KML (.kml) file "
            "of polygons tagged by a 'kind' property: target, no-fly, landing, "
            "obstacle, boundary",
        )
        q.add_argument("--out", required=True, help="the folder for the files")
        q.add_argument(
            "--cell-size",
            type=float,
            metavar="M",
            help="a cell's side on the ground, m (default: 4)",
        )
        q.add_argument(
            "--heading",
            type=float,
            metavar="DEG",
            help="where the grid's rows point, degrees clockwise from true north (default: 0)",
        )
        q.add_argument(
            "--nfz-margin",
            type=float,
            metavar="M",
            help="every waypoint at least this far from every no-fly polygon, m (default: 1.5)",
        )
    grid.set_defaults(func="cpp_mujoco.cli.site:cmd_site_grid")
    plan.add_argument(
        "--altitude",
        type=float,
        metavar="M",
        help="the camera altitude above the take-off point, m (default: 6)",
    )
    plan.add_argument(
        "--speed",
        type=float,
        metavar="M/S",
        help="the cruise speed, a one-cell move's peak, m/s (default: 2.5)",
    )
    plan.add_argument(
        "--battery-wh", type=float, metavar="WH", help="the pack's usable energy, Wh (default: 20)"
    )
    plan.add_argument(
        "--reserve",
        type=float,
        metavar="SHARE",
        help="share of the usable energy left at landing (default: 0.2)",
    )
    plan.add_argument(
        "--climb-speed", type=float, metavar="M/S", help="the take-off climb, m/s (default: 1.5)"
    )
    plan.add_argument(
        "--wind-speed",
        type=float,
        metavar="M/S",
        help="steady wind the mission is planned and flown in, m/s (default: 0)",
    )
    plan.add_argument(
        "--wind-direction",
        type=float,
        metavar="DEG",
        help="where the wind blows from, degrees clockwise from true north (default: 0)",
    )
    plan.add_argument(
        "--min-altitude",
        type=float,
        metavar="M",
        help="the lowest flight altitude allowed, m (default: 2)",
    )
    plan.add_argument(
        "--max-altitude",
        type=float,
        metavar="M",
        help="the highest flight altitude allowed, m (default: 120)",
    )
    plan.add_argument(
        "--planner",
        choices=PLANNER_NAMES,
        default="beam-search",
        help="the reference planner that flies the episode; the wind planners "
        "price moves by --wind-speed (default: %(default)s)",
    )
    plan.add_argument(
        "--agent",
        help="fly an agent instead: a bundled name (general), a checkpoint file, or "
        "NAME+value-beam searching with its values",
    )
    add_any_map_option(plan)
    plan.add_argument(
        "--time-limit",
        type=positive_seconds,
        default=60.0,
        metavar="S",
        help="--planner optimal: the solver's time per solve (default: %(default)s)",
    )
    plan.add_argument(
        "--start",
        help="the take-off cell ROW,COL, a landing cell (default: the "
        "one nearest the middle of the landing polygons)",
    )
    plan.add_argument(
        "--firmware",
        choices=("px4", "ardupilot"),
        default="px4",
        help="the autopilot the plan names (default: %(default)s)",
    )
    plan.add_argument(
        "--seed", type=int_at_least(0), default=0, help="the episode's seed (default: %(default)s)"
    )
    plan.set_defaults(func="cpp_mujoco.cli.site:cmd_site_plan")
