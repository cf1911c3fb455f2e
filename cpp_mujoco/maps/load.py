"""Where a map comes from: a bundled name, a PNG file, or either turned or mirrored."""

from __future__ import annotations

import os
from pathlib import Path

from cpp_mujoco.maps.format import GridMap, MapError, read_png
from cpp_mujoco.maps.symmetry import symmetry_named, turn_map
from cpp_mujoco.util.io import resolve_named_file
from cpp_mujoco.util.resources import bundled_dir


def load_map(source: str | os.PathLike | GridMap) -> GridMap:
    """A bundled map by name (``"A"``), a PNG path, or a ``GridMap`` passed through; a name or
    path with ``~<image>`` (``"C~rot180"``, ``"site.png~mirror"``) is that map turned or mirrored
    (:mod:`cpp_mujoco.maps.symmetry`): the same mission in another orientation."""
    if isinstance(source, GridMap):
        return source
    base, sep, image = os.fspath(source).rpartition("~")
    if sep and base and not Path(source).exists():
        return turn_map(load_map(base), symmetry_named(image))
    where = resolve_named_file(
        source, bundled=bundled_dir("maps"), suffix=".png", kind="map", error=MapError
    )
    path = where.path
    rgb = read_png(path)
    try:
        return GridMap(
            landing=rgb[..., 2] > 0,
            target=rgb[..., 1] > 0,
            nfz=rgb[..., 0] > 0,
            name=where.name,
            source="" if where.bundled else str(path),
            bundled=where.bundled,
        )
    except MapError as e:
        raise MapError(f"{path}: {e}") from e
