"""A flown route as the files a ground station loads: a QGroundControl plan and a MAVLink
waypoint file.

The mission: take off over the start cell to the camera altitude, set the cruise speed, a
waypoint over each cell the route passed (altitudes relative to the take-off point,
``MAV_FRAME_GLOBAL_RELATIVE_ALT``), land on the last cell. Yaw is left to the autopilot (NaN:
``null`` in the plan, as QGroundControl writes it).

``.plan`` (QGroundControl's JSON, as its ``PlanMasterController``, ``MissionController``,
``SimpleMissionItem``, ``GeoFenceController`` and ``RallyPointController`` save it): fileType
``Plan``, version 1; the mission (version 2) with cruise and hover speed, firmware and vehicle
type, the planned home position and the items as ``SimpleItem``; the geofence (version 2) with
one exclusion polygon per no-fly polygon and the site as the inclusion polygon; one rally point
over the landing area. QGroundControl checks only that ``groundStation`` is a string.

``.waypoints`` (``QGC WPL 110``, tab-separated) is written and read by pymavlink's
``MAVWPLoader``; its first line is the home position, as QGroundControl writes it. pymavlink
prints six decimals of a degree: 0.11 m on the ground, far inside a cell.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import shapely
from pymavlink import mavutil, mavwp
from shapely.geometry import Polygon

from cpp_mujoco.sites.budget import FlightSettings
from cpp_mujoco.sites.raster import Georeference, LocalSite
from cpp_mujoco.sites.route import Cell, FlownRoute
from cpp_mujoco.util.io import atomic_path, atomic_write_text

MAV = mavutil.mavlink
NAV_TAKEOFF, NAV_WAYPOINT, NAV_LAND = (
    MAV.MAV_CMD_NAV_TAKEOFF, MAV.MAV_CMD_NAV_WAYPOINT, MAV.MAV_CMD_NAV_LAND,
)  # fmt: skip
DO_CHANGE_SPEED = MAV.MAV_CMD_DO_CHANGE_SPEED
NAV_COMMANDS = (NAV_TAKEOFF, NAV_WAYPOINT, NAV_LAND)  # the items that fly to a position
RELATIVE_ALT = MAV.MAV_FRAME_GLOBAL_RELATIVE_ALT  # 3: altitude above the home position
FIRMWARES = {"px4": MAV.MAV_AUTOPILOT_PX4, "ardupilot": MAV.MAV_AUTOPILOT_ARDUPILOTMEGA}
QGC_RELATIVE_ALTITUDE = 1  # QGroundControl's AltitudeMode for MAV_FRAME_GLOBAL_RELATIVE_ALT
GROUND_STATION = "cpp-mujoco"


@dataclass(frozen=True)
class MissionItem:
    """One MAVLink mission item: command, frame, param1..4, position, and the cell it flies to
    (None for an item without a position)."""

    command: int
    frame: int
    params: tuple[float, float, float, float]
    lat: float
    lon: float
    alt: float
    cell: Cell | None = None


def mission_items(route: FlownRoute, georef: Georeference, flight: FlightSettings):
    """Take-off over the start, the cruise speed, a waypoint per cell after it, the landing."""
    rows, cols = zip(*route.cells, strict=True)
    lons, lats = georef.cell_centres_lonlat(list(rows), list(cols))
    at = [(float(lat), float(lon), cell) for lat, lon, cell in zip(lats, lons, route.cells,
                                                                    strict=True)]  # fmt: skip
    free = (0.0, 0.0, 0.0, math.nan)  # hold, acceptance radius, pass radius: the autopilot's
    alt = float(flight.altitude)
    items = [
        MissionItem(NAV_TAKEOFF, RELATIVE_ALT, free, at[0][0], at[0][1], alt, at[0][2]),
        # ground speed (1), the cruise speed, throttle unchanged (-1)
        MissionItem(
            DO_CHANGE_SPEED,
            MAV.MAV_FRAME_MISSION,
            (1.0, flight.cruise_speed, -1.0, 0.0),
            0.0,
            0.0,
            0.0,
        ),  # fmt: skip
    ]
    items += [MissionItem(NAV_WAYPOINT, RELATIVE_ALT, free, lat, lon, alt, c)
              for lat, lon, c in at[1:]]  # fmt: skip
    lat, lon, cell = at[-1]
    items.append(MissionItem(NAV_LAND, RELATIVE_ALT, free, lat, lon, 0.0, cell))
    return items


def _params(item: MissionItem) -> list[float | None]:
    """The seven params as QGroundControl saves them: NaN as null."""
    values = [*item.params, item.lat, item.lon, item.alt]
    return [None if isinstance(v, float) and math.isnan(v) else v for v in values]


def _lat_lon(polygon: Polygon) -> list[list[float]]:
    """A polygon's exterior as QGroundControl's [[lat, lon], ...], not closed."""
    return [[float(y), float(x)] for x, y in polygon.exterior.coords[:-1]]


def _polygons(geometry) -> list[Polygon]:
    return list(getattr(geometry, "geoms", [geometry]))


def plan_document(
    items: list[MissionItem], local: LocalSite, flight: FlightSettings, firmware: str = "px4"
) -> dict:
    """The QGroundControl ``.plan`` of ``items`` on ``local``'s site, as a JSON-ready dict."""
    if firmware not in FIRMWARES:
        raise ValueError(f"unknown firmware {firmware!r}; choose {', '.join(FIRMWARES)}")
    home = items[0]
    simple = []
    for seq, item in enumerate(items, start=1):
        entry = {
            "type": "SimpleItem",
            "command": int(item.command),
            "frame": int(item.frame),
            "params": _params(item),
            "autoContinue": True,
            "doJumpId": seq,
        }
        if item.command in NAV_COMMANDS:
            entry.update(AltitudeMode=QGC_RELATIVE_ALTITUDE, Altitude=item.alt,
                         AMSLAltAboveTerrain=None)  # fmt: skip
        simple.append(entry)
    site = local.site
    fences = [{"inclusion": False, "polygon": _lat_lon(p), "version": 1}
              for f in site.of_kind("no-fly") for p in _polygons(f.geometry)]  # fmt: skip
    fences += [{"inclusion": True, "polygon": _lat_lon(p), "version": 1}
               for p in _site_polygons(local)]  # fmt: skip
    landing = shapely.union_all([f.geometry for f in site.of_kind("landing")])
    rally = landing.point_on_surface()  # inside the landing area, whatever its shape
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": GROUND_STATION,
        "mission": {
            "version": 2,
            "firmwareType": FIRMWARES[firmware],
            "vehicleType": MAV.MAV_TYPE_QUADROTOR,
            "cruiseSpeed": flight.cruise_speed,
            "hoverSpeed": flight.cruise_speed,
            "globalPlanAltitudeMode": QGC_RELATIVE_ALTITUDE,
            # the take-off point; its altitude above sea level is not known here (0): every
            # item's altitude is relative to it
            "plannedHomePosition": [home.lat, home.lon, 0.0],
            "items": simple,
        },
        "geoFence": {"version": 2, "circles": [], "polygons": fences},
        "rallyPoints": {"version": 2, "points": [[rally.y, rally.x, float(flight.altitude)]]},
    }


def _site_polygons(local: LocalSite) -> list[Polygon]:
    """The inclusion fence: the boundary features, or the grid's rectangle, in lon/lat."""
    boundary = [p for f in local.site.of_kind("boundary") for p in _polygons(f.geometry)]
    if boundary:
        return boundary
    g = local.georef
    rows = [-0.5, -0.5, g.rows - 0.5, g.rows - 0.5]  # the grid's corners, as cell positions
    cols = [-0.5, g.cols - 0.5, g.cols - 0.5, -0.5]
    lons, lats = g.cell_centres_lonlat(rows, cols)
    return [Polygon(zip(lons, lats, strict=True))]


def plan_text(plan: dict) -> str:
    return json.dumps(plan, indent=4, allow_nan=False) + "\n"


def write_plan(path: str | os.PathLike, plan: dict) -> Path:
    return atomic_write_text(path, plan_text(plan))


def waypoint_loader(items: list[MissionItem]) -> mavwp.MAVWPLoader:
    """``items`` in pymavlink's loader, the home position (the take-off point) first."""
    loader = mavwp.MAVWPLoader()
    message = MAV.MAVLink_mission_item_message
    home = items[0]
    loader.add(message(0, 0, 0, MAV.MAV_FRAME_GLOBAL, NAV_WAYPOINT, 1, 1, 0, 0, 0, 0,
                       home.lat, home.lon, 0.0))  # fmt: skip
    for seq, item in enumerate(items, start=1):
        loader.add(message(0, 0, seq, item.frame, item.command, 0, 1, *item.params, item.lat,
                           item.lon, item.alt))  # fmt: skip
    return loader


def write_waypoints(path: str | os.PathLike, items: list[MissionItem]) -> Path:
    """The ``QGC WPL 110`` file of ``items``, written by pymavlink, atomically."""
    with atomic_path(path) as tmp:
        waypoint_loader(items).save(str(tmp))
    return Path(path)


def read_waypoints(path: str | os.PathLike) -> list[MissionItem]:
    """The mission items of a waypoint file, read by pymavlink's loader (the home line left
    out); ValueError if pymavlink cannot read it."""
    loader = mavwp.MAVWPLoader()
    try:
        loader.load(str(path))
    except (mavwp.MAVWPError, ValueError, IndexError) as e:
        raise ValueError(f"{path}: not a waypoint file pymavlink reads ({e})") from None
    items = []
    for i in range(1, loader.count()):
        w = loader.wp(i)
        items.append(MissionItem(int(w.command), int(w.frame),
                                 (w.param1, w.param2, w.param3, w.param4), float(w.x),
                                 float(w.y), float(w.z)))  # fmt: skip
    return items


def items_of_plan(plan: dict) -> list[MissionItem]:
    """The mission items of a ``.plan`` document, read back; ValueError for anything but a
    plan of SimpleItems."""
    if not isinstance(plan, dict) or plan.get("fileType") != "Plan":
        raise ValueError("not a QGroundControl plan (fileType is not 'Plan')")
    items = []
    for k, entry in enumerate(plan.get("mission", {}).get("items", [])):
        if entry.get("type") != "SimpleItem":
            raise ValueError(f"plan item {k} is a {entry.get('type')}; only SimpleItems are read")
        p = [math.nan if v is None else float(v) for v in entry["params"]]
        items.append(MissionItem(int(entry["command"]), int(entry["frame"]),
                                 (p[0], p[1], p[2], p[3]), p[4], p[5], p[6]))  # fmt: skip
    return items
