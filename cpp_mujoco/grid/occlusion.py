"""What the camera sees past obstacles: the line-of-sight rule of Theile et al.'s simulator.

A cell of the square field of view is seen from the UAV's cell P when some ray from P to a cell
on the map's border reaches it before the first obstacle. A ray is a 4-connected Bresenham line
from cell centre to cell centre (x = column, y = row): with d = |Δx|, e = |Δy| and i steps taken
in x, j in y, the next step is in x if e·(4i+3) < d·(4j+3), else in y. The first obstacle stops
the ray and is not seen itself; no-fly cells do not block; nothing is seen from above an
obstacle.

Computed once per map as a table over the field-of-view squares (one entry per cell and square
slot), in the order of :func:`cpp_mujoco.grid.coverage.square_fov_cells`, so every user of the
index table — the MDP, the planners, the bounds — sees through the same rule.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _visible_squares(obstacle: np.ndarray, lo: int, hi: int) -> np.ndarray:  # pragma: no cover
    h, w = obstacle.shape
    side = lo + hi + 1
    border = []
    for x in range(w):
        border.append((0, x))
        border.append((h - 1, x))
    for y in range(h):
        border.append((y, 0))
        border.append((y, w - 1))
    seen = np.zeros((h * w, side * side), dtype=np.bool_)
    for y0 in range(h):
        for x0 in range(w):
            if obstacle[y0, x0]:
                continue  # nothing is seen from above an obstacle
            p = y0 * w + x0
            seen[p, lo * side + lo] = True
            for k in range(len(border)):
                y1, x1 = border[k]
                d, e = abs(x1 - x0), abs(y1 - y0)
                sx = 1 if x1 > x0 else -1
                sy = 1 if y1 > y0 else -1
                x, y, i, j = x0, y0, 0, 0
                while x != x1 or y != y1:
                    if e * (4 * i + 3) < d * (4 * j + 3):
                        x += sx
                        i += 1
                    else:
                        y += sy
                        j += 1
                    dy, dx = y - y0, x - x0
                    if dy < -lo or dy > hi or dx < -lo or dx > hi:
                        break  # the line is monotone: it never comes back into the square
                    if obstacle[y, x]:
                        break
                    seen[p, (dy + lo) * side + dx + lo] = True
    return seen


def visible_squares(obstacle: np.ndarray, side: int) -> np.ndarray:
    """(H·W, side²) bool: slot k of cell p's square is in sight from p (the square's slots as
    :func:`~cpp_mujoco.grid.coverage.square_fov_cells` orders them; off-grid slots are False)."""
    obstacle = np.ascontiguousarray(obstacle, dtype=np.bool_)
    if obstacle.ndim != 2:
        raise ValueError(f"obstacle layer must be 2-D, got shape {obstacle.shape}")
    if side < 1:
        raise ValueError(f"fov side must be >= 1, got {side}")
    return _visible_squares(obstacle, (side - 1) // 2, side // 2)
