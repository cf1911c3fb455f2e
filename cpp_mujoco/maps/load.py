"""Where a map comes from: a bundled name, a PNG file, or either turned or mirrored.

A PNG holds one pixel per cell (R no-fly, G target, B landing, black empty; any channel > 0
counts; alpha below 255 an obstacle). An image drawn at several pixels per cell is read with
``cell_pixels``; without it, an image that is obviously such a drawing (every block of
:data:`OBVIOUS_CELL_PIXELS` or more pixels one colour) is refused with the option to use, rather
than read as a map that many times larger.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from cpp_mujoco.maps.format import GridMap, MapError, read_png
from cpp_mujoco.maps.symmetry import symmetry_named, turn_map
from cpp_mujoco.util.io import resolve_named_file
from cpp_mujoco.util.resources import bundled_dir

OBVIOUS_CELL_PIXELS = 4  # an image of blocks this wide (or wider) is a drawing, not a map
WHITE_SHARE = 0.5  # more pixels than this white (every channel > 0): drawn on white


def cell_block(layers: np.ndarray) -> int:
    """The widest k (dividing both sides) for which every k×k block of the image is one colour:
    the pixels per cell it was drawn at (1: every pixel differs from some neighbour)."""
    h, w = layers.shape[:2]
    side = math.gcd(h, w)
    for k in sorted((d for d in range(2, side + 1) if side % d == 0), reverse=True):
        blocks = layers.reshape(h // k, k, w // k, k, -1)
        if (blocks == blocks[:, :1, :, :1]).all():
            return k
    return 1


def _cells(
    rgba: np.ndarray, path: Path, cell_pixels: int | None, white_background: bool = False
) -> np.ndarray:
    """The (H, W, 4) boolean layers of the image's cells (R no-fly, G target, B landing, alpha
    below 255 obstacle); ``white_background``: white pixels are empty cells (no cell can be all
    three)."""
    layers = np.concatenate([rgba[..., :3] > 0, rgba[..., 3:] < 255], axis=-1)
    colour = layers[..., :3]
    if white_background:
        colour[colour.all(axis=-1)] = False
    h, w = layers.shape[:2]
    white = float(colour.all(axis=-1).mean())
    if white > WHITE_SHARE:
        raise MapError(
            f"{path}: {white:.0%} of the pixels are white; a map is drawn on black (black = "
            "empty; red = no-fly, green = target, blue = landing, any channel > 0 counts)"
        )
    if cell_pixels is None:
        k = cell_block(layers)
        if k >= OBVIOUS_CELL_PIXELS:
            raise MapError(
                f"{path}: the {w}x{h} image is drawn at {k} pixels per cell (a {w // k}x{h // k}"
                f"-cell map); read it with cell_pixels={k} (--cell-pixels {k}), or "
                "cell_pixels=1 to take every pixel as a cell"
            )
        return layers
    if cell_pixels < 1 or h % cell_pixels or w % cell_pixels:
        raise MapError(
            f"{path}: cell_pixels={cell_pixels} does not divide the {w}x{h} image into cells"
        )
    k = cell_pixels
    blocks = layers.reshape(h // k, k, w // k, k, 4)
    mixed = ~(blocks == blocks[:, :1, :, :1]).all(axis=(1, 3, 4))
    if mixed.any():
        r, c = (int(v) for v in np.argwhere(mixed)[0])
        raise MapError(
            f"{path}: with cell_pixels={k}, cell (row {r}, col {c}) holds pixels of different "
            "colours; each cell must be one colour"
        )
    return blocks[:, 0, :, 0]


def load_map(
    source: str | os.PathLike | GridMap, cell_pixels: int | None = None,
    white_background: bool = False,
) -> GridMap:  # fmt: skip
    """A bundled map by name (``"A"``), a PNG path, or a ``GridMap`` passed through; a name or
    path with ``~<image>`` (``"C~rot180"``, ``"site.png~mirror"``) is that map turned or mirrored
    (:mod:`cpp_mujoco.maps.symmetry`): the same mission in another orientation.
    ``cell_pixels``: the image's pixels per cell side (None: one, refusing an image obviously
    drawn at several); ``white_background``: white pixels are empty (a map drawn on white)."""
    if isinstance(source, GridMap):
        return source
    base, sep, image = os.fspath(source).rpartition("~")
    if sep and base and not Path(source).exists():
        turned = load_map(base, cell_pixels, white_background)
        return turn_map(turned, symmetry_named(image))
    where = resolve_named_file(
        source, bundled=bundled_dir("maps"), suffix=".png", kind="map", error=MapError
    )
    path = where.path
    layers = _cells(read_png(path), path, cell_pixels, white_background)
    try:
        return GridMap(
            landing=layers[..., 2],
            target=layers[..., 1],
            nfz=layers[..., 0],
            obstacle=layers[..., 3],
            name=where.name,
            source="" if where.bundled else str(path),
            bundled=where.bundled,
        )
    except MapError as e:
        raise MapError(f"{path}: {e}") from e
