"""From a site file to a checked mission: the chain in one call, everything in memory until
every check has passed, then the files.

:func:`plan_site` reads and rasterises the site, prices the battery in budget units, flies the
policy's episode in MuJoCo from a landing cell, turns the route into mission items, writes the
plan and the waypoint file into a temporary folder, reads both back (the waypoints through
pymavlink), flies the cells the file names in MuJoCo again and runs every check
(:mod:`~cpp_mujoco.sites.checks`). A failed check raises
:class:`~cpp_mujoco.sites.checks.MissionRefused`; nothing is written. :meth:`SiteMission.write`
then writes the map, its georeference, the plan, the waypoint file, the picture and the report,
each atomically.
"""

from __future__ import annotations

import json
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.arena import camera_fovy
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.sites.budget import Battery, Budget, FlightSettings, budget_of, physics_config
from cpp_mujoco.sites.checks import (
    Check,
    Limits,
    MissionRefused,
    cells_of_items,
    check_file,
    check_mission,
    refuse_failures,
)
from cpp_mujoco.sites.export import (
    MissionItem,
    items_of_plan,
    mission_items,
    plan_document,
    read_waypoints,
    write_plan,
    write_waypoints,
)
from cpp_mujoco.sites.figure import mission_plot, png_bytes
from cpp_mujoco.sites.geojson import Site
from cpp_mujoco.sites.raster import LocalSite, RasterConfig, rasterise
from cpp_mujoco.sites.route import ActionReplay, Cell, FlownRoute, actions_between, fly_episode
from cpp_mujoco.util.io import atomic_write_bytes, atomic_write_text, json_default

# the files a mission is written as, in the output folder
FILES = {
    "map": "map.png", "georeference": "georef.json", "plan": "mission.plan",
    "waypoints": "mission.waypoints", "picture": "route.png", "report": "mission.json",
}  # fmt: skip
SITE_PICTURE = "site.png"  # site grid's picture: the polygons over the cells


@dataclass
class SiteMission:
    """A planned, exported, read back, flown and checked mission; :meth:`write` saves it."""

    grid_map: GridMap
    local: LocalSite
    config: PhysicsConfig
    flight: FlightSettings
    budget: Budget
    route: FlownRoute  # the policy's episode in MuJoCo
    items: list[MissionItem]
    plan: dict
    read_back: list[Cell]  # the cells the waypoint file names, read by pymavlink
    from_file: FlownRoute  # those cells flown in MuJoCo
    checks: list[Check]
    picture: bytes = field(repr=False)
    wall_time_s: dict[str, float] = field(default_factory=dict)

    def report(self) -> dict[str, Any]:
        """What ``mission.json`` holds: the site, the grid, the budget, both flights, checks."""
        g, c = self.local.georef, self.config
        return {
            "site": {
                "name": self.local.site.name,
                "source": self.local.site.source,
                "features": len(self.local.features),
            },  # fmt: skip
            "georeference": g.as_dict(),
            "map": {**self.grid_map.identity(), **self.grid_map.counts()},
            "flight": {
                **asdict(self.flight),
                "move_duration_s": c.move_duration,
                "wind_direction_in_map_deg": c.wind_direction,
                # a square camera sees the 3x3 cells around the drone from the altitude
                "camera_fov_deg": camera_fovy(c),
            },
            "budget": {**self.budget.as_dict(), "arithmetic": self.budget.lines()},
            "route": self.route.summary(),
            "from_file": self.from_file.summary(),
            "expected": {
                "coverage_ratio": self.route.coverage_ratio,
                "energy_wh": (self.budget.takeoff_j + self.route.energy_used_j) / 3600,
                "flight_time_s": self.route.flight_time_s,
            },
            "checks": [check.as_dict() for check in self.checks],
            "wall_time_s": self.wall_time_s,
        }

    def write(self, out: str | Path) -> dict[str, Path]:
        """Every file, each atomically, into ``out``; kind → path."""
        out = Path(out)
        paths = {kind: out / name for kind, name in FILES.items()}
        self.grid_map.save(paths["map"])
        self.local.georef.save(paths["georeference"])
        write_plan(paths["plan"], self.plan)
        write_waypoints(paths["waypoints"], self.items)
        atomic_write_bytes(paths["picture"], self.picture)
        report = {**self.report(), "files": {k: p.name for k, p in paths.items()}}
        atomic_write_text(paths["report"], json.dumps(report, indent=2, default=json_default))
        return paths


def default_start(grid_map: GridMap, local: LocalSite) -> Cell:
    """The landing cell nearest the middle of the landing polygons among those whose centre
    lies inside one (so the take-off is over the landing area itself)."""
    cells = np.argwhere(grid_map.landing)
    cell = local.georef.cell_size
    centres = shapely.points((cells[:, 1] + 0.5) * cell, -(cells[:, 0] + 0.5) * cell)
    landing = local.union("landing")
    inside = shapely.distance(centres, landing) <= 1e-9
    pool = np.flatnonzero(inside) if inside.any() else np.arange(len(cells))
    middle = landing.representative_point()
    best = pool[np.argmin(shapely.distance(centres[pool], middle))]
    return int(cells[best, 0]), int(cells[best, 1])


def plan_site(
    site: Site, policy: Any, *, raster: RasterConfig | None = None,
    flight: FlightSettings | None = None, battery: Battery | None = None,
    limits: Limits | None = None, start: Cell | None = None, seed: int = 0,
    firmware: str = "px4", any_map: bool = False,
) -> SiteMission:  # fmt: skip
    """Plan, export, read back, fly again and check ``policy``'s mission on ``site``; raises
    :class:`MissionRefused` (nothing written) when a check fails. Defaults: each config's."""
    raster, flight = raster or RasterConfig(), flight or FlightSettings()
    battery, limits = battery or Battery(), limits or Limits()
    clock = {"start": time.perf_counter()}
    grid_map, local = rasterise(site, raster)
    config = physics_config(flight, raster.cell_size, local.georef.heading_deg)
    if grid_map.has_obstacles:
        try:
            config.check_obstacle_heights()
        except ValueError as e:
            raise ValueError(
                f"the site's obstacles at a {flight.altitude:g} m altitude: {e}"
            ) from None
    budget = budget_of(battery, config)
    start = default_start(grid_map, local) if start is None else _checked_start(grid_map, start)
    clock["grid"] = time.perf_counter()
    route = fly_episode(policy, grid_map, config, budget=budget.units, start=start, seed=seed,
                        any_map=any_map)  # fmt: skip
    clock["policy flight"] = time.perf_counter()
    if not route.landed:
        raise MissionRefused(
            f"mission refused, nothing written: {route.policy} did not land in MuJoCo "
            f"({route.crash_reason}) after {len(route.actions)} actions of {budget.units} units"
        )
    items = mission_items(route, local.georef, flight)
    plan = plan_document(items, local, flight, firmware)
    with tempfile.TemporaryDirectory(prefix="cpp-mujoco-site-") as tmp:
        plan_back = items_of_plan(json.loads(write_plan(Path(tmp) / FILES["plan"], plan)
                                             .read_text(encoding="utf-8")))  # fmt: skip
        file_items = read_waypoints(write_waypoints(Path(tmp) / FILES["waypoints"], items))
    read_back = cells_of_items(file_items, local.georef)
    clock["export"] = time.perf_counter()
    from_file = fly_episode(ActionReplay(actions_between(read_back)), grid_map, config,
                            budget=budget.units, start=read_back[0], seed=seed,
                            any_map=True)  # fmt: skip
    clock["file flight"] = time.perf_counter()
    checks = [
        _agree(plan_back, file_items),
        *check_mission(
            plan_back,
            local,
            limits=limits,
            nfz_margin=raster.nfz_margin,
            budget=budget,
            route=route,
        ),  # fmt: skip
        *check_file(route, read_back, from_file, budget),
    ]
    refuse_failures(checks)
    energy_wh = (budget.takeoff_j + route.energy_used_j) / 3600
    title = (
        f"{route.policy} flown in MuJoCo from {route.start}: {len(route.cells)} waypoints, "
        f"coverage {route.coverage_ratio:.0%}\nenergy {energy_wh:.2f} Wh of "
        f"{battery.usable_wh:g} Wh usable ({battery.reserve:.0%} reserve; budget {budget.units} "
        f"units)\nflown again from the waypoint file: coverage {from_file.coverage_ratio:.0%}, "
        f"landed on {from_file.end}"
    )
    picture = png_bytes(mission_plot(grid_map, local, route, title))
    clock["picture"] = time.perf_counter()
    names = list(clock)
    walls = {b: clock[b] - clock[a] for a, b in zip(names, names[1:], strict=False)}
    walls["total"] = clock[names[-1]] - clock["start"]
    return SiteMission(grid_map, local, config, flight, budget, route, items, plan, read_back,
                       from_file, checks, picture, walls)  # fmt: skip


def _checked_start(grid_map: GridMap, start: Cell) -> Cell:
    row, col = (int(v) for v in start)
    h, w = grid_map.shape
    if not (0 <= row < h and 0 <= col < w and grid_map.landing[row, col]):
        raise ValueError(
            f"start ({row}, {col}) is not a landing cell of the {h}x{w} map; its landing cells: "
            f"{[tuple(int(v) for v in c) for c in np.argwhere(grid_map.landing)[:8]]}"
        )
    return row, col


def _agree(plan: list[MissionItem], waypoints: list[MissionItem]) -> Check:
    """The plan and the waypoint file hold the same items (positions to the file's 1e-6°)."""
    same = len(plan) == len(waypoints) and all(
        a.command == b.command and a.frame == b.frame and abs(a.alt - b.alt) < 1e-3
        and abs(a.lat - b.lat) < 1e-6 and abs(a.lon - b.lon) < 1e-6
        for a, b in zip(plan, waypoints, strict=False)
    )  # fmt: skip
    return Check("the plan and the waypoint file agree", same,
                 f"{len(plan)} plan items, {len(waypoints)} waypoint file items")  # fmt: skip
