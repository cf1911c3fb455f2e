"""A site's polygons from a GeoJSON (or KML) file, each checked before anything is projected.

A site is polygons in WGS84 longitude/latitude, each tagged by a ``kind`` property: ``target``
(what the camera must see), ``no-fly`` (never flown over: roads, houses, airspace),
``landing`` (where the drone takes off and lands), ``obstacle`` (low things that hide the ground
from the camera but are flown over: a tree line) and, optionally, ``boundary`` (the area the
mission may use; without one, the rectangle around every feature). Every refusal is a
:class:`SiteError` that names the feature (its index in the file, its ``name`` property and its
kind), so a person can find it in the GIS tool it was drawn in.
"""

from __future__ import annotations

import json
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.base import BaseGeometry
from shapely.validation import explain_validity

KINDS = ("target", "no-fly", "landing", "obstacle", "boundary")
# other spellings seen in GIS layers, mapped onto KINDS
_ALIASES = {
    "nofly": "no-fly", "no_fly": "no-fly", "no fly": "no-fly", "nfz": "no-fly",
    "land": "landing", "site": "boundary",
}  # fmt: skip
# UTM is defined from 80°S to 84°N; the polar caps need another projection
UTM_LATITUDES = (-80.0, 84.0)


class SiteError(ValueError):
    """A site file or feature the mission cannot be planned from; the message names it."""


@dataclass(frozen=True)
class SiteFeature:
    """One tagged polygon (or multipolygon) of a site, in WGS84 longitude/latitude degrees."""

    index: int  # the feature's position in the file, from 0
    kind: str  # one of KINDS
    name: str  # the feature's ``name`` property ("" if it has none)
    geometry: BaseGeometry  # a valid Polygon or MultiPolygon, x = longitude, y = latitude

    @property
    def label(self) -> str:
        """How messages name the feature: ``feature 3 ('tree line', obstacle)``."""
        return _label(self.index, self.name, self.kind)


def _label(index: int, name: str, kind: str = "") -> str:
    parts = [repr(name)] * bool(name) + [kind] * bool(kind)
    return f"feature {index}" + (f" ({', '.join(parts)})" if parts else "")


@dataclass(frozen=True)
class Site:
    """A site's features, in file order; ``name`` the file's own name or its stem."""

    name: str
    source: str
    features: tuple[SiteFeature, ...]

    def of_kind(self, kind: str) -> list[SiteFeature]:
        return [f for f in self.features if f.kind == kind]

    def centre(self) -> tuple[float, float]:
        """(longitude, latitude) of the middle of every feature's bounds: picks the UTM zone."""
        x0, y0, x1, y1 = shapely.union_all([f.geometry for f in self.features]).bounds
        return (x0 + x1) / 2, (y0 + y1) / 2


def read_site(path: str | os.PathLike) -> Site:
    """The site in ``path``: GeoJSON (``.geojson``, ``.json``) or KML (``.kml``)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SiteError(f"{path}: no such site file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise SiteError(f"{path}: unreadable site file ({e})") from None
    if path.suffix.lower() == ".kml":
        name, raw = path.stem, _kml_features(text, path)
    else:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            raise SiteError(f"{path}: not JSON ({e})") from None
        name, raw = _geojson_features(data, path)
        name = name or path.stem
    return site_from_features(raw, name=name, source=str(path))


def site_from_features(raw: list[tuple[dict, dict | None]], name: str, source: str) -> Site:
    """A checked site from (properties, GeoJSON geometry) pairs in file order."""
    features = tuple(_feature(i, props, geometry) for i, (props, geometry) in enumerate(raw))
    for kind, why in (("target", "nothing to cover"), ("landing", "nowhere to take off and land")):
        if not any(f.kind == kind for f in features):
            raise SiteError(f'{source}: no {kind} polygon: {why} (tag one "kind": "{kind}")')
    return Site(name=name, source=source, features=features)


def _geojson_features(data: Any, path: Path) -> tuple[str, list[tuple[dict, dict | None]]]:
    """(the collection's name, its features' properties and geometries)."""
    if isinstance(data, dict) and data.get("type") == "Feature":
        data = {"type": "FeatureCollection", "features": [data]}
    if not isinstance(data, dict) or data.get("type") != "FeatureCollection":
        raise SiteError(f"{path}: not a GeoJSON FeatureCollection (or Feature)")
    crs = json.dumps(data.get("crs", "CRS84"))
    if "CRS84" not in crs and "4326" not in crs:  # RFC 7946 has no crs; old files may name one
        raise SiteError(f"{path}: crs {data['crs']!r}; a site is WGS84 longitude/latitude")
    features = data.get("features")
    if not isinstance(features, list):
        raise SiteError(f"{path}: 'features' is not a list")
    raw = []
    for i, f in enumerate(features):
        if not isinstance(f, dict) or f.get("type") != "Feature":
            raise SiteError(f"{path}: feature {i} is not a GeoJSON Feature")
        raw.append((f.get("properties") or {}, f.get("geometry")))
    name = data.get("name") if isinstance(data.get("name"), str) else ""
    return name, raw


def _feature(index: int, props: Any, geometry: Any) -> SiteFeature:
    props = props if isinstance(props, dict) else {}
    name = str(props.get("name") or props.get("id") or "")
    kind = _kind(_label(index, name), props.get("kind"))
    label = _label(index, name, kind)
    if not isinstance(geometry, dict) or "type" not in geometry:
        raise SiteError(f"{label} has no geometry")
    kind_of = geometry["type"]
    coords = geometry.get("coordinates")
    if kind_of == "Polygon":
        parts = [coords]
    elif kind_of == "MultiPolygon":
        parts = coords if isinstance(coords, list) else None
    else:
        raise SiteError(f"{label} is a {kind_of}; a site's features are polygons")
    if not parts or not all(isinstance(p, list) and p for p in parts):
        raise SiteError(f"{label} is an empty polygon (no coordinates)")
    polygons = [_polygon(label, rings) for rings in parts]
    shape = polygons[0] if kind_of == "Polygon" else MultiPolygon(polygons)
    if not shape.is_valid:
        raise SiteError(f"{label}: its polygons overlap each other ({explain_validity(shape)})")
    return SiteFeature(index=index, kind=kind, name=name, geometry=shape)


def _kind(label: str, value: Any) -> str:
    if not isinstance(value, str) or not value.strip():
        raise SiteError(f"{label} has no 'kind' property; give one of {', '.join(KINDS)}")
    kind = value.strip().lower()
    kind = _ALIASES.get(kind, kind)
    if kind not in KINDS:
        raise SiteError(f"{label}: unknown kind {value!r}; give one of {', '.join(KINDS)}")
    return kind


def _polygon(label: str, rings: list) -> Polygon:
    """One polygon's rings (exterior first) as a valid shapely Polygon, or the reason why not."""
    checked = [_ring(label, ring) for ring in rings]
    exterior = checked[0]
    if len({p for p in exterior}) < 3:
        raise SiteError(
            f"{label} is an empty polygon ({len(exterior)} positions, "
            f"{len(set(exterior))} distinct; a polygon needs 3 corners)"
        )
    polygon = Polygon(exterior, checked[1:])
    if polygon.is_empty or polygon.area == 0.0:
        raise SiteError(f"{label} is an empty polygon: its corners enclose no area")
    if not polygon.is_valid:
        why = explain_validity(polygon)
        what = "self-intersecting" if "Self-intersection" in why else "not a simple polygon"
        raise SiteError(f"{label} is {what} ({why}); redraw it without crossing edges")
    return polygon


def _ring(label: str, ring: Any) -> list[tuple[float, float]]:
    """A ring's positions as (longitude, latitude), each checked for range and order."""
    if not isinstance(ring, list) or not ring:
        raise SiteError(f"{label} is an empty polygon (a ring without positions)")
    out = []
    for pos in ring:
        if (
            not isinstance(pos, list | tuple)
            or len(pos) < 2
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in pos[:2])
            or not all(math.isfinite(v) for v in pos[:2])
        ):
            raise SiteError(f"{label}: position {pos!r} is not [longitude, latitude]")
        lon, lat = float(pos[0]), float(pos[1])
        if abs(lat) > 90 and abs(lon) <= 90:
            raise SiteError(
                f"{label}: latitude {lat:.7g} is beyond ±90°: its coordinates look swapped "
                f"(GeoJSON and KML give longitude first: [{lat:.7g}, {lon:.7g}]?)"
            )
        if abs(lon) > 180 or abs(lat) > 90:
            raise SiteError(f"{label}: ({lon:g}, {lat:g}) is not a longitude and a latitude")
        if not UTM_LATITUDES[0] <= lat <= UTM_LATITUDES[1]:
            raise SiteError(
                f"{label}: latitude {lat:g} is outside the UTM zones (80°S..84°N); if the site "
                "is not polar, its coordinates look swapped (longitude comes first)"
            )
        out.append((lon, lat))
    return out


# ----------------------------------------------------------------------------- KML
def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _children(element: ET.Element, name: str) -> list[ET.Element]:
    return [e for e in element.iter() if _local(e.tag) == name]


def _kml_features(text: str, path: Path) -> list[tuple[dict, dict | None]]:
    """Each Placemark's name, its ``kind`` (ExtendedData ``Data`` or ``SimpleData``) and its
    polygons, as GeoJSON-like pairs for :func:`site_from_features`."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as e:
        raise SiteError(f"{path}: not KML ({e})") from None
    raw = []
    for placemark in _children(root, "Placemark"):
        props: dict[str, str] = {}
        for child in placemark:
            if _local(child.tag) == "name" and child.text:
                props["name"] = child.text.strip()
        for data in _children(placemark, "Data") + _children(placemark, "SimpleData"):
            if data.get("name") == "kind":
                values = [v for v in data.iter() if _local(v.tag) == "value"]
                props["kind"] = ((values[0].text if values else data.text) or "").strip()
        polygons = [_kml_polygon(p) for p in _children(placemark, "Polygon")]
        if not polygons:
            raw.append((props, {"type": "Point or LineString"}))
        elif len(polygons) == 1:
            raw.append((props, {"type": "Polygon", "coordinates": polygons[0]}))
        else:
            raw.append((props, {"type": "MultiPolygon", "coordinates": polygons}))
    return raw


def _kml_polygon(polygon: ET.Element) -> list[list[list[float]]]:
    rings = []
    for boundary in ("outerBoundaryIs", "innerBoundaryIs"):
        for part in _children(polygon, boundary):
            for coords in _children(part, "coordinates"):
                rings.append(_kml_coordinates(coords.text or ""))
    return rings


def _kml_coordinates(text: str) -> list[list[float]]:
    out = []
    for token in text.split():
        try:
            out.append([float(v) for v in token.split(",")])
        except ValueError:
            out.append([token])  # refused by _ring with the position named
    return out
