"""The general network's two views of a map centred on the UAV, and a per-map table of them.

:func:`centre_on_uav` defines them: a (2·side−1)² canvas with the UAV in the middle and no-fly
outside the map; the local view is its central crop, the global view its adaptive average pool.
:func:`centred_views` computes both from the map itself, without the canvas.

:class:`MapViewCache`: a batch whose rows all fly one map (a protocol's episodes, the value
beam's paths) differs row to row only in its coverage and the UAV's cell, yet the views of
every layer of every row were a quarter of the value beam's time on 32×32 maps. The views of a
0/1 grid are sums of whole cells (exact in float32 whatever their order) and the steps after
the sums are elementwise, so views put together from a per-cell table of the map's layers and
the coverage layer alone are the very numbers the full computation gives: tested equal bit for
bit, views and Q-values.
"""

from __future__ import annotations

from functools import lru_cache

import torch
import torch.nn.functional as F

from cpp_mujoco.agent.network import COVERAGE_CHANNEL, NFZ_CHANNEL, POSITION_CHANNEL

MAX_TABLE_CELLS = 64 * 64  # maps up to this many cells get a table (~50 MB at most)
MIN_TABLE_ROWS = 32  # smaller batches are computed in full (a table costs one row per cell)
Views = tuple[torch.Tensor, torch.Tensor]  # (local (B,C,l,l), global (B,C,g,g))


def centre_on_uav(grid: torch.Tensor, side: int) -> torch.Tensor:
    """(B,5,H,W) → (B,5,2·side−1,2·side−1), the UAV (the one-hot position channel) in the
    middle; outside the map is no-fly (ones in the no-fly channel, zeros elsewhere).

    The definition of the network's views; :func:`centred_views` computes them without the
    canvas and is tested against it. On the CPU each map is pasted into its canvas, on a GPU
    one gather avoids B kernel launches."""
    b, _, h, w = grid.shape
    if side < max(h, w):
        raise ValueError(f"canvas side {side} is smaller than the {h}x{w} map")
    row, col = uav_cells(grid)
    if grid.device.type != "cpu":
        return _centre_gather(grid, side, row, col)
    canvas = grid.new_zeros((b, grid.shape[1], 2 * side - 1, 2 * side - 1))
    canvas[:, NFZ_CHANNEL] = 1.0
    for i, (r, c) in enumerate(zip(row.tolist(), col.tolist(), strict=True)):
        top, left = side - 1 - r, side - 1 - c
        canvas[i, :, top : top + h, left : left + w] = grid[i]
    return canvas


def _centre_gather(grid: torch.Tensor, side: int, row: torch.Tensor, col: torch.Tensor):
    """:func:`centre_on_uav` as one batched gather from the no-fly-padded maps."""
    p = side - 1
    padded = F.pad(grid, (p, p, p, p), value=0.0)
    padded[:, NFZ_CHANNEL] = F.pad(grid[:, NFZ_CHANNEL], (p, p, p, p), value=1.0)
    span = torch.arange(2 * side - 1, device=grid.device)
    rows = (row[:, None] + span)[:, :, None]  # padded row of canvas row i: row + i
    cols = (col[:, None] + span)[:, None, :]
    batch = torch.arange(grid.shape[0], device=grid.device)[:, None, None]
    return padded.permute(0, 2, 3, 1)[batch, rows, cols].permute(0, 3, 1, 2)


def centred_views(
    grid: torch.Tensor, side: int, local_size: int, global_size: int
) -> tuple[torch.Tensor, torch.Tensor]:
    """The centre ``local_size``² crop and the ``global_size``² adaptive average pool of
    ``centre_on_uav(grid, side)``, computed from the map itself: each view is R · map · Cᵀ per
    channel, R and C the 0/1 matrices of which map rows and columns fall into each view cell
    (looked up by the UAV's row and column), plus the no-fly cells outside the map.

    Why: the (B,5,63,63) canvas costs a per-sample paste loop and a pool over 10 MB for 128
    rows; the few small batched matmuls read only the maps. The crop is exact; the pool sums
    the same cells (exact for 0/1 inputs) and divides as ``adaptive_avg_pool2d`` does."""
    return views_at(grid, *uav_cells(grid), side, local_size, global_size)


def views_at(
    grid: torch.Tensor,
    row: torch.Tensor,
    col: torch.Tensor,
    side: int,
    local_size: int,
    global_size: int,
    nfz: bool = True,
) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`centred_views` with the UAV at (``row``, ``col``); ``nfz``: the grid holds the
    no-fly layer, which is one outside the map (without it, any layers: each is viewed alone)."""
    b, _, h, w = grid.shape
    if side < max(h, w):
        raise ValueError(f"canvas side {side} is smaller than the {h}x{w} map")
    rows = _selection(h, side, local_size, global_size, grid.device, grid.dtype)
    cols = rows if w == h else _selection(w, side, local_size, global_size, grid.device, grid.dtype)
    (rg, rl, rg_in, rl_in, counts), (cg, cl, cg_in, cl_in, _) = rows, cols
    glob = _sandwich(rg[row], grid, cg[col])
    if nfz:
        area = counts[:, None] * counts[None, :]
        glob[:, NFZ_CHANNEL] += area - rg_in[row][:, :, None] * cg_in[col][:, None, :]
    glob = glob / counts[:, None] / counts[None, :]  # as adaptive_avg_pool2d: / kh / kw
    local = _sandwich(rl[row], grid, cl[col])
    if nfz:
        local[:, NFZ_CHANNEL] += 1.0 - rl_in[row][:, :, None] * cl_in[col][:, None, :]
    return local, glob


def _sandwich(r: torch.Tensor, grid: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
    """r (B,m,H) · grid (B,K,H,W) · cᵀ (B,W,n) per channel → (B,K,m,n), as two plain bmm. The
    result is laid out channels-last: the convolutions run faster on it (measured 10–20 %
    forward, 8–10 % backward)."""
    b, k, h, w = grid.shape
    x = torch.bmm(grid.reshape(b, k * h, w), c.transpose(1, 2))  # (B, K·H, n)
    n = x.shape[-1]
    x = x.view(b, k, h, n).permute(0, 2, 3, 1).reshape(b, h, n * k)  # (B, H, n·K)
    y = torch.bmm(r, x)  # (B, m, n·K)
    return y.view(b, -1, n, k).permute(0, 3, 1, 2)


@lru_cache(maxsize=32)
def _selection(
    n: int, side: int, local_size: int, global_size: int, device: torch.device, dtype: torch.dtype
) -> tuple[torch.Tensor, ...]:
    """For an n-cell map axis, indexed by the UAV's cell p: which map cells fall into each
    global cell (p, g, n) and each local cell (p, l, n), how many (p, g) and (p, l); and the
    canvas cells of each global cell (g,). The map's cell y lies on canvas cell y + side−1−p."""
    length = 2 * side - 1
    out = torch.arange(global_size)
    start = out * length // global_size  # adaptive_avg_pool2d's windows
    end = -(-(out + 1) * length // global_size)
    p = torch.arange(n)[:, None, None]
    canvas = torch.arange(n)[None, None, :] + side - 1 - p  # (p, 1, n)
    glob = (canvas >= start[None, :, None]) & (canvas < end[None, :, None])
    half = local_size // 2
    local = torch.arange(n)[None, None, :] == p - half + torch.arange(local_size)[None, :, None]
    tables = (glob, local, glob.sum(-1), local.sum(-1), end - start)
    return tuple(t.to(device=device, dtype=dtype) for t in tables)


def uav_cells(grid: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(row, col) of each row's UAV: the argmax of its position layer."""
    b, _, h, w = grid.shape
    flat = grid[:, POSITION_CHANNEL].reshape(b, -1).argmax(dim=1)
    return flat // w, flat % w


class MapViewCache:
    """The views of one map's layers (all but coverage) with the UAV in each of its cells,
    for a network's view sizes; :meth:`views` serves a batch from it where it can."""

    def __init__(self, side: int, local_size: int, global_size: int):
        self.sizes = (side, local_size, global_size)
        self.layers: torch.Tensor | None = None  # (C, H, W) the map it was built for
        self.local: torch.Tensor | None = None  # (H·W, l, l, C), by the UAV's flat cell
        self.glob: torch.Tensor | None = None  # (H·W, g, g, C)

    def views(self, grid: torch.Tensor) -> Views:
        """``centred_views(grid, *sizes)``, from the table (rebuilt for a new map) where every
        row holds one map and a one-hot UAV layer, else computed in full."""
        b, c, h, w = grid.shape
        if b < MIN_TABLE_ROWS or h * w > MAX_TABLE_CELLS or not _one_map(grid):
            return centred_views(grid, *self.sizes)
        if not self._holds(_map_layers(grid[0])):
            self._build(grid[:1])
        row, col = uav_cells(grid)
        coverage = grid[:, COVERAGE_CHANNEL : COVERAGE_CHANNEL + 1]
        own_local, own_glob = views_at(coverage, row, col, *self.sizes, nfz=False)
        cell = row * w + col
        return _merge(self.local, own_local, cell), _merge(self.glob, own_glob, cell)

    def _holds(self, layers: torch.Tensor) -> bool:
        """Whether the table was built for these very map layers (same device and dtype)."""
        old = self.layers
        same_kind = old is not None and (old.shape, old.device, old.dtype) == (
            layers.shape, layers.device, layers.dtype,
        )  # fmt: skip
        return same_kind and torch.equal(old, layers)

    def _build(self, row: torch.Tensor) -> None:
        """The full views of ``row``'s map with the UAV in each cell (coverage: its own)."""
        _, c, h, w = row.shape
        cells = h * w
        grid = row.expand(cells, c, h, w).clone()
        grid[:, POSITION_CHANNEL] = 0.0
        grid[:, POSITION_CHANNEL].view(cells, -1)[torch.arange(cells), torch.arange(cells)] = 1.0
        local, glob = centred_views(grid, *self.sizes)
        # kept channels last, as the views are laid out: a gathered row needs no reordering
        self.local, self.glob = (v.permute(0, 2, 3, 1).contiguous() for v in (local, glob))
        self.layers = _map_layers(row[0]).clone()


def _map_layers(grid: torch.Tensor) -> torch.Tensor:
    """(C,H,W) → the layers of the map itself: all but coverage and the UAV (its last two of
    five; an obstacle layer follows them)."""
    return torch.cat([grid[:COVERAGE_CHANNEL], grid[POSITION_CHANNEL + 1 :]])


def _one_map(grid: torch.Tensor) -> bool:
    """Whether every row holds the same map layers and a UAV layer of one 1 and zeros (the
    views place the UAV at its argmax)."""
    for layers in (grid[:, :COVERAGE_CHANNEL], grid[:, POSITION_CHANNEL + 1 :]):
        if layers.shape[1] and not torch.equal(layers.amax(0), layers.amin(0)):
            return False
    flat = grid[:, POSITION_CHANNEL].reshape(grid.shape[0], -1)
    # every row sums to 1 (so holds a non-zero) and there are as many non-zeros as rows
    return bool((flat.sum(1) == 1).all()) and int(flat.count_nonzero()) == flat.shape[0]


def _merge(table: torch.Tensor, own: torch.Tensor, cell: torch.Tensor) -> torch.Tensor:
    """The ``table``'s rows of each cell with the coverage views ``own`` in their channel,
    laid out channels last as :func:`_sandwich` lays them (the convolutions see one layout)."""
    out = table[cell].permute(0, 3, 1, 2)
    out[:, COVERAGE_CHANNEL] = own[:, 0]
    return out
