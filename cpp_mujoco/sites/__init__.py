"""A real site in, a mission a real drone can fly out: ``cpp-mujoco site``.

The chain, one module each: :mod:`~cpp_mujoco.sites.geojson` reads the site's polygons (GeoJSON,
or KML) and refuses bad ones by name; :mod:`~cpp_mujoco.sites.raster` projects them to the UTM
zone of the site and rasterises them into a :class:`~cpp_mujoco.maps.GridMap` with its
georeference; :mod:`~cpp_mujoco.sites.budget` turns a battery into a budget through the
physics' own calibration; :mod:`~cpp_mujoco.sites.route` flies a policy's episode in MuJoCo;
:mod:`~cpp_mujoco.sites.export` writes the route as a QGroundControl plan and a MAVLink
waypoint file; :mod:`~cpp_mujoco.sites.checks` checks the exported mission before a pilot gets
it, and flies it again from the file; :mod:`~cpp_mujoco.sites.figure` draws it;
:mod:`~cpp_mujoco.sites.mission` runs the chain and writes the files.

The package needs the ``site`` extra (shapely, pyproj, pymavlink); :func:`missing_extra` says
which of them are absent, so the command line can say so in one line before importing any.
"""

from __future__ import annotations

import importlib.util

SITE_EXTRA = ("shapely", "pyproj", "pymavlink")


def missing_extra() -> list[str]:
    """The packages of the ``site`` extra that are not installed."""
    return [name for name in SITE_EXTRA if importlib.util.find_spec(name) is None]
