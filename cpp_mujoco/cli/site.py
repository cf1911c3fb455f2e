"""The ``site`` command: a real site's polygons to a grid map (``site grid``), and on to a
checked mission a drone can fly (``site plan``); its parser is in :mod:`cpp_mujoco.cli.parsers`.

The work is :mod:`cpp_mujoco.sites`'s, which needs the ``site`` extra; without it the command
says which packages are missing in one line. Options left out take the defaults of the configs
they set (:class:`~cpp_mujoco.sites.raster.RasterConfig`,
:class:`~cpp_mujoco.sites.budget.FlightSettings`, :class:`~cpp_mujoco.sites.budget.Battery`,
:class:`~cpp_mujoco.sites.checks.Limits`), so each default lives in one place.
"""

from __future__ import annotations

import sys
from pathlib import Path

from cpp_mujoco import sites
from cpp_mujoco.cli.options import check_agent_file, parse_start
from cpp_mujoco.planners import make_planner
from cpp_mujoco.planners.optimal_solver import SolverOptions
from cpp_mujoco.util.io import atomic_write_bytes


def _require_extra() -> None:
    missing = sites.missing_extra()
    if missing:
        raise ValueError(
            f"the site command needs the site extra ({', '.join(missing)} missing): "
            "pip install -e '.[site]'"
        )


def _given(cls, args, **names: str):
    """``cls`` from the options that were given (``field=option``); the rest its defaults."""
    return cls(**{f: getattr(args, o) for f, o in names.items() if getattr(args, o) is not None})


def _raster(args):
    from cpp_mujoco.sites.raster import RasterConfig  # optional: the site extra

    return _given(RasterConfig, args, cell_size="cell_size", heading="heading",
                  nfz_margin="nfz_margin")  # fmt: skip


def _policy(args):
    """``--agent`` (a bundled name or checkpoint) or ``--planner`` (beam search by default)."""
    if args.agent:
        from cpp_mujoco.agent.value_beam import load_policy, split_search  # heavy: torch

        check_agent_file(split_search(args.agent)[0])
        return load_policy(args.agent)
    optimal = {"options": SolverOptions(time_limit_s=args.time_limit)}
    return make_planner(args.planner, optimal=optimal)


def cmd_site_grid(args) -> None:
    """``site grid SITE --out DIR``: the map and its georeference, nothing flown."""
    _require_extra()
    from cpp_mujoco.sites.figure import png_bytes, site_plot  # optional: the site extra
    from cpp_mujoco.sites.geojson import read_site  # optional: the site extra
    from cpp_mujoco.sites.mission import FILES, SITE_PICTURE  # optional: the site extra
    from cpp_mujoco.sites.raster import rasterise  # optional: the site extra

    grid_map, local = rasterise(read_site(args.site), _raster(args))
    picture = png_bytes(site_plot(grid_map, local))  # drawn before any file is written
    out = Path(args.out)
    grid_map.save(out / FILES["map"])
    local.georef.save(out / FILES["georeference"])
    atomic_write_bytes(out / SITE_PICTURE, picture)
    g, counts = local.georef, grid_map.counts()
    print(
        f"site {local.site.name}: {len(local.features)} polygons -> {g.rows}x{g.cols} cells of "
        f"{g.cell_size:g} m at heading {g.heading_deg:g}° ({g.crs}): {counts['target']} target, "
        f"{counts['landing']} landing, {counts['nfz']} no-fly, {counts['obstacle']} obstacle"
    )
    for path in (FILES["map"], FILES["georeference"], SITE_PICTURE):
        print(f"wrote {out / path}")


def cmd_site_plan(args) -> None:
    """``site plan SITE --out DIR``: plan, export, read back, fly again, check, write."""
    _require_extra()
    from cpp_mujoco.sites.budget import Battery, FlightSettings  # optional: the site extra
    from cpp_mujoco.sites.checks import Limits  # optional: the site extra
    from cpp_mujoco.sites.geojson import read_site  # optional: the site extra
    from cpp_mujoco.sites.mission import plan_site  # optional: the site extra

    site = read_site(args.site)  # bad input fails before anything is loaded or flown
    raster = _raster(args)
    flight = _given(FlightSettings, args, altitude="altitude", cruise_speed="speed",
                    wind_speed="wind_speed", wind_direction="wind_direction")  # fmt: skip
    battery = _given(Battery, args, usable_wh="battery_wh", reserve="reserve",
                     climb_speed="climb_speed")  # fmt: skip
    limits = _given(Limits, args, min_altitude="min_altitude", max_altitude="max_altitude")
    start = parse_start(args.start, "18,6")
    policy = _policy(args)
    if flight.wind_speed > 0 and not (args.planner or "").endswith("-wind") and not args.agent:
        print(
            f"note: {args.planner} prices no wind; safe-greedy-wind and beam-search-wind price "
            "each move by the wind", file=sys.stderr,
        )  # fmt: skip
    mission = plan_site(
        site, policy, raster=raster, flight=flight, battery=battery, limits=limits,
        start=start, seed=args.seed, firmware=args.firmware, any_map=args.any_map,
    )  # fmt: skip
    paths = mission.write(args.out)
    g, route, counts = mission.local.georef, mission.route, mission.grid_map.counts()
    print(
        f"site {site.name}: {g.rows}x{g.cols} cells of {g.cell_size:g} m at heading "
        f"{g.heading_deg:g}° ({g.crs}); {counts['target']} target, {counts['landing']} landing"
    )
    for line in mission.budget.lines():
        print(f"budget: {line}")
    report = mission.report()["expected"]
    print(
        f"{route.policy} from {route.start}: {len(route.cells)} waypoints, landed on {route.end}, "
        f"coverage {route.coverage_ratio:.1%}, energy {report['energy_wh']:.2f} Wh, flight "
        f"{route.flight_time_s / 60:.1f} min"
    )
    for check in mission.checks:
        print(f"check passed: {check.name} ({check.detail})")
    walls = ", ".join(f"{k} {v:.1f} s" for k, v in mission.wall_time_s.items())
    print(f"wall time: {walls}")
    for kind, path in paths.items():
        print(f"{kind}: {path}")
