"""Grid cells ↔ world coordinates: the one conversion every part of the project uses.

World frame: x east, y north, z up; the map is centred on the origin, so cell (row, col) — row 0
the north edge — has its centre at ``x = (col + ½ − W/2)·cell``, ``y = (H/2 − row − ½)·cell``.
The arena, the flight, the camera, the recordings and the grid missions all convert through
:class:`GridGeometry`, so a change of convention (or of ``cell_size``) cannot leave one of them
drawing or flying somewhere else. Light on purpose (no MuJoCo): grid-only code imports it too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from cpp_mujoco.maps import GridMap


@dataclass(frozen=True)
class GridGeometry:
    """Conversions between grid cells and world coordinates for an H × W grid."""

    height: int
    width: int
    cell_size: float  # m, the ground side of one cell (``PhysicsConfig.cell_size``)

    @classmethod
    def of(cls, grid_map: GridMap, cell_size: float) -> GridGeometry:
        return cls(*grid_map.shape, cell_size)

    def cell_center(self, row, col):
        """World (x, y) of the centre of cell (row, col); rows and cols may be numpy arrays."""
        cs = self.cell_size
        return ((col + 0.5 - self.width / 2) * cs, (self.height / 2 - row - 0.5) * cs)

    def centers(self) -> np.ndarray:
        """(H·W, 2) world xy of every cell centre, in flat cell order ``row·W + col``."""
        rows, cols = np.divmod(np.arange(self.height * self.width), self.width)
        return np.stack(self.cell_center(rows, cols), 1)

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) containing world point (x, y); may lie outside the grid."""
        inv = 1.0 / self.cell_size
        return (math.floor(self.height / 2 - y * inv), math.floor(x * inv + self.width / 2))

    def cell_index(self, x: float, y: float) -> int | None:
        """Flat index ``row·W + col`` of the cell containing (x, y); None off the grid."""
        row, col = self.cell_of(x, y)
        if 0 <= row < self.height and 0 <= col < self.width:
            return row * self.width + col
        return None

    def centred_in(self, x_min: float, x_max: float, y_min: float, y_max: float):
        """(rows, cols): the ranges of rows and columns whose centres lie in the box (clipped to
        the grid) — the candidates a footprint polygon can contain."""
        inv, h2, w2 = 1.0 / self.cell_size, self.height / 2, self.width / 2
        # centre x = (c + ½ − W/2)·cs ∈ [x_min, x_max]  ⇔  c ∈ [x_min/cs + W/2 − ½, x_max/cs + …]
        c_lo = max(0, math.ceil(x_min * inv + w2 - 0.5))
        c_hi = min(self.width - 1, math.floor(x_max * inv + w2 - 0.5))
        r_lo = max(0, math.ceil(h2 - y_max * inv - 0.5))
        r_hi = min(self.height - 1, math.floor(h2 - y_min * inv - 0.5))
        return range(r_lo, r_hi + 1), range(c_lo, c_hi + 1)

    @property
    def half_extent(self) -> tuple[float, float]:
        """(x, y) half sides of the map on the ground, m."""
        return (self.width * self.cell_size / 2, self.height * self.cell_size / 2)
