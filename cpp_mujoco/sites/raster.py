"""A site's polygons projected to metres and rasterised into a grid map, with its georeference.

Projection: the UTM zone of the site's centre (WGS84 / UTM, ``EPSG:326zz`` north, ``327zz``
south; pyproj), where a metre is a metre to 0.04 % (UTM's scale factor) anywhere in a site of a
few hundred metres. The grid is turned by ``heading`` (degrees clockwise from true north: where
its rows point "up"); true north differs from the zone's grid north by the meridian convergence,
which is measured at the site and added, so a heading of 0 puts the columns on the meridian.

Local frame: x metres along the rows (the grid's "east"), y metres along the columns (its
"north"), origin at the north-west corner of cell (0, 0); cell (row, col) spans
x ∈ [col, col + 1)·cell and y ∈ (−(row + 1), −row]·cell. The grid is the rectangle around the
``boundary`` features, or around every feature without one, centred on it.

Rasterising (shapely): a cell is target or landing where the polygons cover at least half of it,
no-fly and obstacle where they overlap it at all (conservative), and no-fly too where it is not
wholly inside the boundary. The no-fly polygons are grown by ``nfz_margin`` less half a cell
first: a cell that overlaps no polygon has its centre half a cell from each already, so every
flyable cell's centre keeps the margin. Obstacle cells are neither target nor landing (the map
format's rule); landing cells under no-fly are dropped.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass
from functools import cache
from pathlib import Path

import numpy as np
import shapely
from pyproj import Transformer
from shapely.geometry.base import BaseGeometry

from cpp_mujoco.maps import GridMap, MapError
from cpp_mujoco.maps.format import MAX_SIDE
from cpp_mujoco.sites.geojson import Site, SiteError, SiteFeature
from cpp_mujoco.util.io import atomic_write_text

HALF = 0.5  # target and landing: the share of a cell the polygons must cover
OVERLAP = 1e-6  # no-fly, obstacle: any overlap above this share of a cell (float noise below)
OVERLAP_M2 = 1e-3  # m², two features overlap above this area (touching edges do not)
# m, how far a boundary may miss a grid edge: coordinates of 7 decimals are 1 cm apart
BOUNDARY_SLACK_M = 0.02


@dataclass(frozen=True)
class RasterConfig:
    """How a site becomes a grid."""

    cell_size: float = 4.0  # m, a cell's side on the ground (the physics' default cell)
    heading: float = 0.0  # deg clockwise from true north: where the grid's rows point "up"
    # m, at least this far from every no-fly polygon for every waypoint (a cell centre): about a
    # consumer GNSS receiver's horizontal error
    nfz_margin: float = 1.5

    def __post_init__(self) -> None:
        for name, low in (("cell_size", 0.0), ("nfz_margin", -1e-12)):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > low):
                raise ValueError(f"{name} must be a finite number > {max(low, 0):g}, got {value}")
        if not math.isfinite(self.heading):
            raise ValueError(f"heading must be a finite number of degrees, got {self.heading}")


@dataclass(frozen=True)
class Georeference:
    """Where a grid lies on the earth: what the georeference file holds."""

    crs: str  # the projected CRS of the local frame, "EPSG:32615"
    origin_lon: float  # deg, the north-west corner of cell (0, 0)
    origin_lat: float
    origin_easting: float  # m, the same corner in the CRS
    origin_northing: float
    cell_size: float  # m
    heading_deg: float  # deg clockwise from true north of the grid's "up"
    rotation_deg: float  # deg clockwise from the CRS's grid north: heading + convergence
    rows: int
    cols: int

    def to_projected(self, x, y):
        """CRS (easting, northing) of local (x, y); arrays welcome."""
        t = math.radians(self.rotation_deg)
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        return (
            self.origin_easting + x * math.cos(t) + y * math.sin(t),
            self.origin_northing - x * math.sin(t) + y * math.cos(t),
        )

    def to_local(self, easting, northing):
        """Local (x, y) of CRS (easting, northing); arrays welcome."""
        t = math.radians(self.rotation_deg)
        de = np.asarray(easting, dtype=float) - self.origin_easting
        dn = np.asarray(northing, dtype=float) - self.origin_northing
        return de * math.cos(t) - dn * math.sin(t), de * math.sin(t) + dn * math.cos(t)

    def cell_centres_lonlat(self, rows, cols):
        """(longitude, latitude) of the centres of cells (rows, cols)."""
        x = (np.asarray(cols, dtype=float) + 0.5) * self.cell_size
        y = -(np.asarray(rows, dtype=float) + 0.5) * self.cell_size
        return _to_wgs84(self.crs).transform(*self.to_projected(x, y))

    def lonlat_to_cells(self, lon, lat):
        """(row, col) as floats of points (lon, lat): a cell centre is a whole number."""
        x, y = self.to_local(*_to_crs(self.crs).transform(lon, lat))
        return -np.asarray(y) / self.cell_size - 0.5, np.asarray(x) / self.cell_size - 0.5

    def as_dict(self) -> dict:
        return {
            **asdict(self),
            "origin": "the north-west corner of cell (0, 0); row 0 is the grid's north edge",
            "local_frame": "metres from the origin: x towards higher columns, y towards row 0",
        }

    def save(self, path: str | os.PathLike) -> None:
        atomic_write_text(path, json.dumps(self.as_dict(), indent=2) + "\n")

    @classmethod
    def load(cls, path: str | os.PathLike) -> Georeference:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        return cls(**{k: data[k] for k in cls.__dataclass_fields__})


@cache
def _to_crs(crs: str) -> Transformer:
    return Transformer.from_crs("EPSG:4326", crs, always_xy=True)


@cache
def _to_wgs84(crs: str) -> Transformer:
    return Transformer.from_crs(crs, "EPSG:4326", always_xy=True)


def utm_crs(lon: float, lat: float) -> str:
    """The WGS84 / UTM zone of (lon, lat) as an EPSG code (the regular 6° zones)."""
    zone = min(int((lon + 180.0) // 6.0) + 1, 60)
    return f"EPSG:{(32600 if lat >= 0 else 32700) + zone}"


def true_north_in_crs(crs: str, lon: float, lat: float) -> float:
    """Degrees clockwise from the CRS's grid north to true north at (lon, lat)."""
    e0, n0 = _to_crs(crs).transform(lon, lat)
    e1, n1 = _to_crs(crs).transform(lon, lat + 1e-4)
    return math.degrees(math.atan2(e1 - e0, n1 - n0))


@dataclass(frozen=True)
class LocalSite:
    """A site's features in the local frame (metres), beside the grid they were rasterised to."""

    site: Site
    georef: Georeference
    features: tuple[tuple[SiteFeature, BaseGeometry], ...]

    def union(self, kind: str) -> BaseGeometry:
        """Every feature of ``kind`` as one geometry (empty when there is none)."""
        return shapely.union_all([g for f, g in self.features if f.kind == kind])

    @property
    def area(self) -> BaseGeometry:
        """Where the mission may fly: the boundary features, or the grid's rectangle."""
        boundary = self.union("boundary")
        if not boundary.is_empty:
            return boundary
        g = self.georef
        return shapely.box(0.0, -g.rows * g.cell_size, g.cols * g.cell_size, 0.0)


def project_site(site: Site, config: RasterConfig) -> LocalSite:
    """The site in the local frame of a grid fitted around it (size checked first)."""
    lon, lat = site.centre()
    crs = utm_crs(lon, lat)
    to_crs = _to_crs(crs)
    projected = [(f, _transform(f.geometry, to_crs.transform)) for f in site.features]
    heading = config.heading % 360.0
    rotation = heading + true_north_in_crs(crs, lon, lat)
    turn = Georeference(crs, 0, 0, 0.0, 0.0, config.cell_size, heading, rotation, 0, 0)
    turned = [(f, _transform(g, turn.to_local)) for f, g in projected]
    frame = [g for f, g in turned if f.kind == "boundary"] or [g for _, g in turned]
    x0, y0, x1, y1 = shapely.union_all(frame).bounds
    cell = config.cell_size
    cols, rows = (max(1, math.ceil((extent - 2 * BOUNDARY_SLACK_M) / cell))
                  for extent in (x1 - x0, y1 - y0))  # fmt: skip
    if max(rows, cols) > MAX_SIDE:
        raise SiteError(
            f"{site.source}: the site spans {x1 - x0:.0f} m x {y1 - y0:.0f} m at heading "
            f"{heading:g}°: {cols} x {rows} cells of {cell:g} m, over the map limit of "
            f"{MAX_SIDE} cells a side; give a cell of at least "
            f"{math.ceil(max(x1 - x0, y1 - y0) / MAX_SIDE * 10) / 10:g} m or split the site"
        )
    left = x0 - (cols * cell - (x1 - x0)) / 2  # the grid centred on the frame
    top = y1 + (rows * cell - (y1 - y0)) / 2
    east, north = turn.to_projected(left, top)
    origin_lon, origin_lat = _to_wgs84(crs).transform(float(east), float(north))
    georef = Georeference(
        crs=crs, origin_lon=float(origin_lon), origin_lat=float(origin_lat),
        origin_easting=float(east), origin_northing=float(north), cell_size=float(cell),
        heading_deg=heading, rotation_deg=rotation, rows=rows, cols=cols,
    )  # fmt: skip
    local = tuple((f, _transform(g, georef.to_local)) for f, g in projected)
    return LocalSite(site=site, georef=georef, features=local)


def _transform(geometry: BaseGeometry, fn) -> BaseGeometry:
    """``geometry`` with every (x, y) mapped by ``fn(x_array, y_array) -> (x, y)``."""
    return shapely.transform(geometry, lambda xy: np.column_stack(fn(xy[:, 0], xy[:, 1])))


def rasterise(site: Site, config: RasterConfig | None = None) -> tuple[GridMap, LocalSite]:
    """The grid map of ``site`` and the site in its local frame (``.georef`` places it)."""
    config = config or RasterConfig()
    local = project_site(site, config)
    _refuse_overlaps(local, "landing", ("no-fly", "a drone cannot land where it may not fly"))
    _refuse_overlaps(local, "landing", ("obstacle", "nothing lands in an obstacle"))
    g = local.georef
    cell = g.cell_size
    rows, cols = np.divmod(np.arange(g.rows * g.cols), g.cols)
    boxes = shapely.box(cols * cell, -(rows + 1) * cell, (cols + 1) * cell, -rows * cell)

    def share(geometry: BaseGeometry) -> np.ndarray:
        out = np.zeros(boxes.size)
        if geometry.is_empty:
            return out.reshape(g.rows, g.cols)
        shapely.prepare(geometry)
        hit = shapely.intersects(boxes, geometry)
        out[hit] = shapely.area(shapely.intersection(boxes[hit], geometry)) / cell**2
        return out.reshape(g.rows, g.cols)

    grow = config.nfz_margin - cell / 2
    nfz_zones = local.union("no-fly")
    if grow > 0 and not nfz_zones.is_empty:
        nfz_zones = nfz_zones.buffer(grow)
    nfz = share(nfz_zones) > OVERLAP
    if not local.union("boundary").is_empty:
        inside = share(local.union("boundary").buffer(BOUNDARY_SLACK_M, join_style="mitre"))
        nfz |= inside < 1.0 - OVERLAP
    obstacle = share(local.union("obstacle")) > OVERLAP
    target = (share(local.union("target")) >= HALF) & ~obstacle
    landing = (share(local.union("landing")) >= HALF) & ~obstacle & ~nfz
    for layer, kind in ((landing, "landing"), (target, "target")):
        if not layer.any():
            names = ", ".join(f.label for f in site.of_kind(kind))
            raise SiteError(
                f"{names}: no cell of {cell:g} m is covered by half and clear of obstacles"
                + (" and no-fly cells" if kind == "landing" else "")
                + f" (no-fly margin {config.nfz_margin:g} m); draw it larger or use smaller cells"
            )
    try:
        grid_map = GridMap(landing=landing, target=target, nfz=nfz, name=site.name,
                           source=site.source, obstacle=obstacle)  # fmt: skip
    except MapError as e:
        raise SiteError(f"{site.source}: {e}") from None
    return grid_map, local


def _refuse_overlaps(local: LocalSite, kind: str, other: tuple[str, str]) -> None:
    """A feature of ``kind`` overlapping one of ``other[0]`` is refused, both named."""
    others = [(f, g) for f, g in local.features if f.kind == other[0]]
    for f, g in local.features:
        if f.kind != kind:
            continue
        for o, h in others:
            area = g.intersection(h).area
            if area > OVERLAP_M2:
                raise SiteError(f"{f.label} overlaps {o.label} by {area:.1f} m²: {other[1]}")
