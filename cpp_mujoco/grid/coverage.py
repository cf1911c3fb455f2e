"""Coverage bookkeeping: which cells the camera has seen, and how many targets are new.

Shared by both backends: the grid MDP marks the square field of view, the physics backend marks
the camera footprint; both then call :func:`mark_seen`.
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.maps import GridMap


def square_fov_masks(grid_map: GridMap, side: int) -> np.ndarray:
    """(H·W, H·W) bool: row ``p`` is the side×side square centred on cell ``p``, clipped.

    An even side extends one cell further to the south/east than to the north/west.
    """
    if side < 1:
        raise ValueError(f"fov side must be >= 1, got {side}")
    h, w = grid_map.shape
    rows, cols = np.divmod(np.arange(h * w), w)
    lo, hi = (side - 1) // 2, side // 2
    dr = rows[None, :] - rows[:, None]
    dc = cols[None, :] - cols[:, None]
    return (dr >= -lo) & (dr <= hi) & (dc >= -lo) & (dc <= hi)


def mark_seen(coverage: np.ndarray, seen: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Mark ``seen`` cells in ``coverage`` in place; return how many target cells are new per row.

    ``coverage`` and ``seen`` are (N, H·W) bool, ``target`` is (H·W,) bool.
    """
    new = seen > coverage  # seen and not yet covered
    coverage |= seen
    new &= target
    return new.sum(axis=1)
