"""The square grid's symmetries: rotations by quarter turns and mirror images of a map.

The grid MDP has no preferred direction — its four moves are the compass's, the camera's view
is a square, the return rule counts moves — so a map turned or mirrored, flown from the turned
start with the turned actions, is the same mission (and the same returns). A square map has 8
such images (the dihedral group D4), any other map the 4 that keep its shape. A map in
calm air keeps this symmetry; the grid's wind turns with the map (:func:`turn_wind`).

Two uses: training on the 8 images of a map a user brings (``named_symmetries``: the network
learns the site, not one orientation of it), and averaging a network's Q-values over the
images of the state it sees (``symmetric_q``, :class:`~cpp_mujoco.agent.policy.GreedyAgent`):
an estimate of Q that is itself symmetric, the mean of 8 readings of one network.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from cpp_mujoco.maps.format import GridMap, MapError


class Symmetry(NamedTuple):
    """Mirror left–right (``mirror``), then turn ``quarter_turns`` × 90° counter-clockwise."""

    mirror: bool
    quarter_turns: int

    @property
    def name(self) -> str:
        turn = f"rot{90 * self.quarter_turns}" if self.quarter_turns else ""
        return "-".join(p for p in ("mirror" if self.mirror else "", turn) if p) or "identity"

    def keeps_shape(self, shape: tuple[int, int]) -> bool:
        """Whether an H×W map keeps its shape (an odd number of quarter turns swaps H and W)."""
        return self.quarter_turns % 2 == 0 or shape[0] == shape[1]


IDENTITY = Symmetry(False, 0)
SYMMETRIES = tuple(Symmetry(m, k) for m in (False, True) for k in range(4))  # D4, identity first


def symmetries_of(shape: tuple[int, int]) -> tuple[Symmetry, ...]:
    """The symmetries that map an H×W map onto an H×W map: 8 for a square, else 4."""
    return tuple(s for s in SYMMETRIES if s.keeps_shape(shape))


def turn_cells(cells: np.ndarray, symmetry: Symmetry) -> np.ndarray:
    """``cells`` (…, H, W) as the map's image: the last two axes mirrored and turned (a view)."""
    cells = np.asarray(cells)
    if symmetry.mirror:
        cells = np.flip(cells, axis=-1)
    return np.rot90(cells, k=symmetry.quarter_turns, axes=(-2, -1))


def turn_move(d_row, d_col, symmetry: Symmetry):
    """A move (Δrow, Δcol) — scalars or arrays — as it is on the image (rows grow southward)."""
    if symmetry.mirror:
        d_col = -d_col
    for _ in range(symmetry.quarter_turns):  # a counter-clockwise turn: (r, c) → (−c, r)
        d_row, d_col = -d_col, d_row
    return d_row, d_col


def turn_wind(wind: np.ndarray, symmetry: Symmetry) -> np.ndarray:
    """(…, 2) east and north wind components (m/s) on the image: east is +column, north −row."""
    wind = np.asarray(wind)
    d_row, d_col = turn_move(-wind[..., 1], wind[..., 0], symmetry)
    return np.stack([d_col, -d_row], axis=-1).astype(wind.dtype, copy=False)


def turn_map(grid_map: GridMap, symmetry: Symmetry) -> GridMap:
    """The map's image, named ``<name>~<symmetry>`` (the identity: the map itself)."""
    if symmetry == IDENTITY:
        return grid_map
    layers = {
        k: turn_cells(getattr(grid_map, k), symmetry)
        for k in ("landing", "target", "nfz", "obstacle")
    }
    origin = f"{grid_map.identity()['map_source']} ({grid_map.label}), image {symmetry.name}"
    name = f"{grid_map.label}~{symmetry.name}"
    return replace(grid_map, **layers, name=name, source=origin, bundled=False)


def symmetry_named(name: str) -> Symmetry:
    """The symmetry of a name (``rot90``, ``mirror-rot180`` …); ``MapError`` for another."""
    for symmetry in SYMMETRIES:
        if symmetry.name == name:
            return symmetry
    names = ", ".join(s.name for s in SYMMETRIES)
    raise MapError(f"unknown map image {name!r}: one of {names}")


def map_images(grid_map: GridMap) -> list[GridMap]:
    """The map and its distinct images (a symmetric map has fewer than 8)."""
    seen, out = set(), []
    for symmetry in symmetries_of(grid_map.shape):
        image = turn_map(grid_map, symmetry)
        if image.digest not in seen:
            seen.add(image.digest)
            out.append(image)
    return out
