"""The checks an exported mission passes before a pilot gets it.

On the mission's own positions (metres in the site's local frame, from each item's latitude
and longitude): every position inside the site, every one at least the no-fly margin from every
no-fly polygon, the landing inside a landing polygon, every flight altitude within the limits,
the route's energy (take-off and the flight MuJoCo flew) within what the pack may spend.
On the file: the waypoint file read back by pymavlink names the route's cells, one by one, and
flown in MuJoCo from those cells (:func:`cells_of_items`, then the moves between them) it sees
the same target cells and lands on the same cell.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
import shapely

from cpp_mujoco.sites.budget import Budget
from cpp_mujoco.sites.export import NAV_COMMANDS, NAV_LAND, NAV_TAKEOFF, MissionItem
from cpp_mujoco.sites.raster import Georeference, LocalSite
from cpp_mujoco.sites.route import Cell, FlownRoute

SNAP_M = 0.25  # m, a waypoint read back lies this close to a cell centre (the file: 0.11 m)
TOLERANCE_M = 1e-6  # m, float noise in the geometric checks


class MissionRefused(ValueError):
    """A mission that failed a check: nothing is written; the message names each failure."""


@dataclass(frozen=True)
class Limits:
    """What the mission must keep to."""

    min_altitude: float = 2.0  # m above the take-off point, every waypoint at least
    max_altitude: float = 120.0  # m above the take-off point: the EU open category's ceiling

    def __post_init__(self) -> None:
        if not (math.isfinite(self.min_altitude) and math.isfinite(self.max_altitude)):
            raise ValueError("altitude limits must be finite numbers")
        if not 0 <= self.min_altitude <= self.max_altitude:
            raise ValueError(
                f"altitude limits must be 0 <= min <= max, got {self.min_altitude:g}.."
                f"{self.max_altitude:g}"
            )


@dataclass(frozen=True)
class Check:
    """One check: its name, whether it passed, and the figures that decided it."""

    name: str
    passed: bool
    detail: str

    def as_dict(self) -> dict:
        return asdict(self)


def local_points(items: list[MissionItem], georef: Georeference) -> np.ndarray:
    """(N, 2) local x, y of the items that fly to a position."""
    nav = [i for i in items if i.command in NAV_COMMANDS]
    rows, cols = georef.lonlat_to_cells([i.lon for i in nav], [i.lat for i in nav])
    cell = georef.cell_size
    return np.stack([(np.asarray(cols) + 0.5) * cell, -(np.asarray(rows) + 0.5) * cell], axis=1)


def check_mission(
    items: list[MissionItem], local: LocalSite, *, limits: Limits, nfz_margin: float,
    budget: Budget, route: FlownRoute,
) -> list[Check]:  # fmt: skip
    """The checks on the mission's positions, altitudes and energy."""
    nav = [i for i in items if i.command in NAV_COMMANDS]
    points = shapely.points(local_points(items, local.georef))
    checks = []
    outside = shapely.distance(points, local.area) > TOLERANCE_M
    checks.append(Check(
        "inside the site", not outside.any(),
        f"{int(outside.sum())} of {len(nav)} positions outside"
        + (f", first item {int(np.argmax(outside))}" if outside.any() else ""),
    ))  # fmt: skip
    nfz = local.union("no-fly")
    if nfz.is_empty:
        checks.append(Check("clear of no-fly", True, "the site has no no-fly polygon"))
    else:
        gap = shapely.distance(points, nfz)
        worst = int(np.argmin(gap))
        checks.append(Check(
            "clear of no-fly", bool(gap.min() >= nfz_margin - TOLERANCE_M),
            f"closest {gap.min():.2f} m (position {worst}), margin {nfz_margin:g} m",
        ))  # fmt: skip
    last = nav[-1]
    in_landing = (
        last.command == NAV_LAND
        and shapely.distance(points[-1], local.union("landing")) <= TOLERANCE_M
    )
    checks.append(Check(
        "lands in a landing polygon", bool(in_landing),
        f"the last item is MAV_CMD {last.command}"
        + ("" if last.command != NAV_LAND else " (land) at its cell's centre"),
    ))  # fmt: skip
    flying = [i.alt for i in nav if i.command != NAV_LAND]
    checks.append(Check(
        "altitude within limits",
        all(limits.min_altitude <= a <= limits.max_altitude for a in flying),
        f"{min(flying):g}..{max(flying):g} m, limits {limits.min_altitude:g}.."
        f"{limits.max_altitude:g} m",
    ))  # fmt: skip
    checks.append(_energy_check("energy within the pack", budget, route))
    checks.append(Check(
        "lands in physics", route.landed,
        "landed" if route.landed else f"did not land: {route.crash_reason}",
    ))  # fmt: skip
    return checks


def _energy_check(name: str, budget: Budget, route: FlownRoute) -> Check:
    spend = budget.usable_j - budget.reserve_j
    used = budget.takeoff_j + route.energy_used_j
    return Check(
        name,
        bool(used <= spend),
        f"take-off {budget.takeoff_j / 3600:.3f} Wh + flight {route.energy_used_j / 3600:.2f} Wh"
        f" = {used / 3600:.2f} Wh of {spend / 3600:.2f} Wh (usable less the reserve)",
    )


def cells_of_items(items: list[MissionItem], georef: Georeference) -> list[Cell]:
    """The cells a mission read from a file flies over: the take-off's, each waypoint's, the
    landing's (a repeat left out). ValueError for a position that is not a cell centre of
    this grid, or a mission that does not take off first and land last."""
    nav = [i for i in items if i.command in NAV_COMMANDS]
    if not nav or nav[0].command != NAV_TAKEOFF or nav[-1].command != NAV_LAND:
        raise ValueError("the mission does not take off first and land last")
    rows, cols = georef.lonlat_to_cells([i.lon for i in nav], [i.lat for i in nav])
    cells: list[Cell] = []
    for k, (r, c) in enumerate(zip(np.atleast_1d(rows), np.atleast_1d(cols), strict=True)):
        cell = (int(round(float(r))), int(round(float(c))))
        off = math.hypot(r - cell[0], c - cell[1]) * georef.cell_size
        if off > SNAP_M or not (0 <= cell[0] < georef.rows and 0 <= cell[1] < georef.cols):
            raise ValueError(
                f"position {k} of the mission lies {off:.2f} m from the nearest cell centre "
                f"{cell} of the {georef.rows}x{georef.cols} grid (at most {SNAP_M} m)"
            )
        if not cells or cells[-1] != cell:
            cells.append(cell)
    return cells


def check_file(route: FlownRoute, read_back: list[Cell], flown: FlownRoute,
               budget: Budget) -> list[Check]:  # fmt: skip
    """The waypoint file read back and flown from its cells, against the route it came from."""
    same_cells = read_back == route.cells
    first = next(
        (k for k, (a, b) in enumerate(zip(read_back, route.cells, strict=False)) if a != b), None
    )
    missed = int((route.seen & ~flown.seen).sum())
    extra = int((flown.seen & ~route.seen).sum())
    return [
        Check(
            "the file names the route's cells", same_cells,
            f"{len(read_back)} cells read back, {len(route.cells)} flown"
            + (f"; first difference at waypoint {first}" if first is not None else ""),
        ),
        Check(
            "flown from the file: the same coverage", missed == 0 and extra == 0,
            f"{int(flown.seen.sum())} target cells seen, {int(route.seen.sum())} by the policy"
            f" ({missed} missed, {extra} more)",
        ),
        Check(
            "flown from the file: lands on the same cell",
            flown.landed and flown.end == route.end,
            f"{'landed' if flown.landed else 'did not land'} on {flown.end}, the route on "
            f"{route.end}",
        ),
        _energy_check("flown from the file: energy within the pack", budget, flown),
    ]  # fmt: skip


def refuse_failures(checks: list[Check]) -> None:
    """Raise :class:`MissionRefused` naming every check that failed."""
    failed = [c for c in checks if not c.passed]
    if failed:
        raise MissionRefused(
            "mission refused, nothing written: "
            + "; ".join(f"{c.name} failed ({c.detail})" for c in failed)
        )
