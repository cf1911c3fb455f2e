"""Coverage bookkeeping: which cells the camera has seen, and how many targets are new.

Shared by both backends: the grid MDP marks the square field of view through an index table
(:func:`view_cells`: the square, less what obstacles hide; :func:`mark_fov`), the physics
backend marks the camera footprint as a mask (:func:`mark_seen`). Nothing here is
(cells × cells): memory must grow with the map, not with its square.
"""

from __future__ import annotations

import functools

import numpy as np

from cpp_mujoco.grid.occlusion import visible_squares
from cpp_mujoco.maps import GridMap


def _fov_reach(side: int) -> tuple[int, int]:
    """Cells the square reaches to the north/west and to the south/east of its centre.

    An even side extends one cell further to the south/east than to the north/west.
    """
    if side < 1:
        raise ValueError(f"fov side must be >= 1, got {side}")
    return (side - 1) // 2, side // 2


def square_fov_cells(shape: tuple[int, int], side: int) -> tuple[np.ndarray, np.ndarray]:
    """The side×side square centred on each cell, clipped to the grid, as an index table.

    Returns ``(cells, valid)``, both (H·W, side²): ``cells[p]`` the flat cells of ``p``'s square;
    entries that fall off the grid are ``valid`` False and repeat ``p`` itself, so the table can
    be used for marking without a bounds check and each seen cell is counted once.
    """
    lo, hi = _fov_reach(side)
    h, w = shape
    rows, cols = np.divmod(np.arange(h * w), w)
    d = np.arange(-lo, hi + 1)
    r = rows[:, None, None] + d[None, :, None]
    c = cols[:, None, None] + d[None, None, :]
    valid = ((r >= 0) & (r < h) & (c >= 0) & (c < w)).reshape(h * w, side * side)
    flat = (r * w + c).reshape(h * w, side * side)
    cells = np.where(valid, flat, np.arange(h * w)[:, None]).astype(np.intp)
    return cells, valid


def view_valid(obstacle: np.ndarray, side: int) -> np.ndarray:
    """(H·W, side²) bool: the slots of each cell's square on the grid and in sight past
    ``obstacle`` (:mod:`cpp_mujoco.grid.occlusion`); the square's own where there is none. The
    sight table is kept per obstacle layer: the MDP, the graph and the agent's inputs of one map
    share it."""
    obstacle = np.asarray(obstacle, dtype=bool)
    _, valid = square_fov_cells(obstacle.shape, side)
    if obstacle.any():
        valid &= _sight(np.packbits(obstacle).tobytes(), obstacle.shape, side)
    return valid


@functools.lru_cache(maxsize=32)
def _sight(packed: bytes, shape: tuple[int, int], side: int) -> np.ndarray:
    obstacle = np.unpackbits(np.frombuffer(packed, dtype=np.uint8), count=shape[0] * shape[1])
    sight = visible_squares(obstacle.reshape(shape).astype(bool), side)
    sight.flags.writeable = False
    return sight


def view_cells(grid_map: GridMap, side: int) -> tuple[np.ndarray, np.ndarray]:
    """The map's field-of-view table: :func:`square_fov_cells`, with the entries that obstacles
    hide (:func:`view_valid`) ``valid`` False and pointing at the cell itself, as off-grid
    entries do, so marking the table never marks a hidden cell. On a map without obstacles it is
    the square table itself (the rule hides nothing there: every square slot on the grid is on
    some ray to the border)."""
    cells, _ = square_fov_cells(grid_map.shape, side)
    valid = view_valid(grid_map.obstacle, side)
    if grid_map.has_obstacles:
        cells = np.where(valid, cells, np.arange(cells.shape[0])[:, None])
    return cells, valid


def view_counts(mask: np.ndarray, cells: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(N, H·W) int32: how many ``mask`` cells (an (N, H·W) bool) each cell's view holds, through
    a :func:`view_cells` table (:func:`square_fov_counts` is the same where nothing is hidden)."""
    return (mask[:, cells] & valid).sum(axis=2, dtype=np.int32)


def square_fov_counts(mask: np.ndarray, shape: tuple[int, int], side: int) -> np.ndarray:
    """(N, H·W) int32: how many ``mask`` cells (an (N, H·W) bool) each cell's square holds.

    The same squares as :func:`square_fov_cells`, summed as a separable box filter — O(N·H·W·side)
    instead of a (cells × cells) product.
    """
    lo, hi = _fov_reach(side)
    h, w = shape
    n = mask.shape[0]
    padded = np.zeros((n, h + side - 1, w + side - 1), dtype=np.int32)
    padded[:, lo : lo + h, lo : lo + w] = mask.reshape(n, h, w)
    by_rows = padded[:, :h, :].copy()
    for i in range(1, side):
        by_rows += padded[:, i : i + h, :]
    out = by_rows[:, :, :w].copy()
    for j in range(1, side):
        out += by_rows[:, :, j : j + w]
    return out.reshape(n, h * w)


def square_fov_union(shape: tuple[int, int], side: int, cells: np.ndarray) -> np.ndarray:
    """(H·W,) bool: every cell seen from any of the flat ``cells`` (e.g. a trajectory)."""
    fov_cells, valid = square_fov_cells(shape, side)
    seen = np.zeros(shape[0] * shape[1], dtype=bool)
    seen[fov_cells[cells][valid[cells]]] = True
    return seen


def square_fov_masks(grid_map: GridMap, side: int) -> np.ndarray:
    """(H·W, H·W) bool: row ``p`` is the side×side square centred on cell ``p``, clipped.

    Quadratic in the cells (4 GB at 256×256): a reference for tests on small maps only; the
    MDP and the planners use :func:`square_fov_cells`, figures :func:`square_fov_union`.
    """
    cells, valid = square_fov_cells(grid_map.shape, side)
    owner = np.broadcast_to(np.arange(cells.shape[0])[:, None], cells.shape)
    masks = np.zeros((cells.shape[0], cells.shape[0]), dtype=bool)
    masks[owner[valid], cells[valid]] = True
    return masks


def mark_fov(
    coverage: np.ndarray,
    fov_cells: np.ndarray,
    fov_counted: np.ndarray,
    position: np.ndarray,
    rows: np.ndarray | None = None,
) -> np.ndarray:
    """Mark each row's field of view in ``coverage`` in place; return its new target cells (N,).

    ``coverage`` is (N, H·W) bool and C-contiguous (it is written through a flat view);
    ``fov_cells`` the table of :func:`square_fov_cells`; ``fov_counted`` (H·W, side²) bool marks
    the entries to count (valid and a target); ``position`` (N,) flat cells. Only ``rows`` (default
    all) are marked; the others report 0.
    """
    if not coverage.flags.c_contiguous:
        raise ValueError("coverage must be C-contiguous to be marked in place")
    n, cells = coverage.shape
    flat = coverage.reshape(-1)
    at = position if rows is None else position[rows]
    index = fov_cells.take(at, axis=0)  # take: several times faster than [] for one row
    if n > 1:
        index += ((np.arange(n) if rows is None else rows) * cells)[:, None]
    new = fov_counted.take(at, axis=0) > flat.take(index)  # counted and not yet covered
    flat[index] = True
    if rows is None:
        return new.sum(axis=1)
    newly = np.zeros(n, dtype=np.int64)
    newly[rows] = new.sum(axis=1)
    return newly


def mark_seen(coverage: np.ndarray, seen: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Mark ``seen`` cells in ``coverage`` in place; return how many target cells are new per row.

    ``coverage`` and ``seen`` are (N, H·W) bool, ``target`` is (H·W,) bool.
    """
    new = seen > coverage  # seen and not yet covered
    coverage |= seen
    new &= target
    return new.sum(axis=1)
