"""The general networks' obstacle input: the map's obstacle layer as one more grid channel, and
what the obstacles hide from the camera for the moves to new targets.

Why: on a map with obstacles (a city's buildings, low buildings, trees) the camera does not see
past them (:mod:`cpp_mujoco.grid.occlusion`), so a network that reads landing, target, no-fly,
coverage and position only cannot tell which targets a cell shows; a policy refuses such maps
unless its network reads the layer (:attr:`GreedyAgent.reads_obstacles
<cpp_mujoco.agent.policy.GreedyAgent.reads_obstacles>`).

* The channel (``obstacle_input=True`` on :class:`~cpp_mujoco.agent.general_network.
  GeneralQNetwork` or :class:`~cpp_mujoco.agent.fcn_network.FCNQNetwork`): the observation's
  ``obstacle`` layer after the UAV's position (:data:`~cpp_mujoco.agent.network.OBSTACLE_CHANNEL`),
  zeros on a map without obstacles and on a pool's padding — the value the global-local canvas
  holds outside the map, so padding still changes no Q-value.
* :func:`targets_in_view`: which cells show an unseen target, through each map's view table
  (:func:`view_valid`: the grid's square less what its obstacles hide, as
  :func:`~cpp_mujoco.grid.coverage.view_cells` builds it), for the moves to new targets
  (:mod:`~cpp_mujoco.agent.target_input`).
* :func:`widen_for_obstacle_input`: a network's weights without the channel → with it, at zero
  weight, so ``--init-from`` a network without it starts from the very same Q-values on maps
  without obstacles.

The rays of the view rule end at the map's border, so a padded grid is read at the map's own
extent (:func:`used_cells`): the top-left rectangle up to the last row and column holding a cell
that is not plain no-fly. Padding is plain no-fly; a map whose own last rows or columns are plain
no-fly (no-fly, no landing, target, obstacle or UAV) is read without them — its rays then end one
border nearer, which may change its moves to new targets, never a rule (the rules read the
observation's map through :func:`~cpp_mujoco.grid.graph.graph_from_observation`). Generated maps
end in no such row or column (``tests/test_general_obstacles.py``).
"""

from __future__ import annotations

from functools import lru_cache
from itertools import product

import numpy as np
import torch
import torch.nn.functional as F

from cpp_mujoco.agent.network import (
    LANDING_CHANNEL,
    NFZ_CHANNEL,
    OBSTACLE_CHANNEL,
    POSITION_CHANNEL,
    TARGET_CHANNEL,
)
from cpp_mujoco.grid.coverage import view_valid as coverage_view_valid

# view tables kept, as bits keyed by the packed obstacle layer: ≈ 1.5 kB a 32×32 map, so the
# bundled run's pool (8,192 maps of each of two sizes) fits in ≈ 25 MB — a minibatch draws its
# rows from the whole pool, and a miss costs the ray casting again (≈ 2 ms a 32×32 map)
CACHE_MAPS = 16_384


def reads_obstacles(grid: torch.Tensor) -> bool:
    """Whether (B,C,H,W) network input holds the obstacle channel."""
    return grid.shape[1] > OBSTACLE_CHANNEL


def used_cells(grid: torch.Tensor) -> torch.Tensor:
    """(B,H,W) bool: the cells that are not plain no-fly (no-fly and neither landing, target,
    the UAV nor, where the grid has the channel, an obstacle). Padding is plain no-fly."""
    plain = (
        (grid[:, NFZ_CHANNEL] > 0.5)
        & (grid[:, LANDING_CHANNEL] <= 0.5)
        & (grid[:, TARGET_CHANNEL] <= 0.5)
        & (grid[:, POSITION_CHANNEL] <= 0.5)
    )
    if reads_obstacles(grid):
        plain &= grid[:, OBSTACLE_CHANNEL] <= 0.5
    return ~plain


def _extent(used: torch.Tensor) -> list[tuple[int, int]]:
    """(rows, columns) of each grid's map: up to its last row and column with a used cell."""
    h, w = used.shape[-2:]
    rows = h - used.any(dim=2).flip(1).int().argmax(dim=1)
    cols = w - used.any(dim=1).flip(1).int().argmax(dim=1)
    return list(zip(rows.tolist(), cols.tolist(), strict=True))


def view_valid(obstacle: np.ndarray, side: int) -> np.ndarray:
    """(h, w, side²) bool: the slots of each cell's side×side square that its camera sees on an
    h×w map with these obstacles — :func:`~cpp_mujoco.grid.coverage.view_valid` per cell."""
    obstacle = np.asarray(obstacle, dtype=bool)
    return coverage_view_valid(obstacle, side).reshape(*obstacle.shape, side * side)


@lru_cache(maxsize=CACHE_MAPS)
def _view_bits(packed: bytes, shape: tuple[int, int], side: int) -> np.ndarray:
    """:func:`view_valid` of one map's obstacles (``packed``: its layer's packed bits), slot
    first ((side², h, w): each slot's plane is contiguous), as packed bits."""
    cells = shape[0] * shape[1]
    obstacle = np.unpackbits(np.frombuffer(packed, dtype=np.uint8), count=cells).reshape(shape)
    bits = np.packbits(np.moveaxis(view_valid(obstacle, side), 2, 0))
    bits.flags.writeable = False
    return bits


def _view_tables(obstacle: np.ndarray, extents: list[tuple[int, int]], side: int) -> np.ndarray:
    """(R, side², H, W) bool: each (H,W) ``obstacle`` layer's view table at its map's extent,
    the map top-left (no slot of a cell outside the map is seen)."""
    tables = np.zeros((obstacle.shape[0], side * side, *obstacle.shape[1:]), dtype=bool)
    for table, layer, (h, w) in zip(tables, obstacle, extents, strict=True):
        bits = _view_bits(np.packbits(layer[:h, :w]).tobytes(), (h, w), side)
        table[:, :h, :w] = np.unpackbits(bits, count=side * side * h * w).reshape(-1, h, w)
    return tables


def _square(unseen: torch.Tensor, side: int) -> torch.Tensor:
    """The cells whose side×side square (``side`` odd) holds an unseen cell: a 3×3 max pool of
    the 0/1 layer, computed as ORs of shifted rows, then of shifted columns (a single-channel
    ``max_pool2d`` costs 15–20× more on the CPU, measured at 264 rows of 16×16 and 32×32)."""
    half = side // 2
    h, w = unseen.shape[-2:]
    padded = F.pad(unseen.to(torch.uint8), (half, half, half, half))
    across = padded[..., 0:w].clone()
    for dx in range(1, side):
        across |= padded[..., dx : dx + w]
    out = across[..., 0:h, :].clone()
    for dy in range(1, side):
        out |= across[..., dy : dy + h, :]
    return out.bool()


_MAP_CHANNELS = [LANDING_CHANNEL, TARGET_CHANNEL, NFZ_CHANNEL, OBSTACLE_CHANNEL]


def _one_map_valid(grid: torch.Tensor, obstacle: torch.Tensor, side: int) -> torch.Tensor | None:
    """(1,side²,H,W): the one view table of a batch whose rows are all on one map (its layers
    equal row by row, as a search's or a protocol's batch is), read once for every row; None
    for a batch of several maps. A row's extent is its map's and its UAV's cell
    (:func:`used_cells`), so one extent serves where every UAV is inside the map's."""
    layers = grid[:, _MAP_CHANNELS]
    if not bool((layers == layers[:1]).all()):
        return None
    first = grid[:1].clone()
    first[:, POSITION_CHANNEL] = 0.0  # the map's own cells, without the UAV
    ((rows, cols),) = _extent(used_cells(first))
    at = grid[:, POSITION_CHANNEL].flatten(1)
    cell = at.argmax(dim=1)
    flown = at.amax(dim=1) > 0.5
    w = grid.shape[-1]
    if bool(((cell // w >= rows) | (cell % w >= cols))[flown].any()):
        return None  # a UAV beyond the map's cells: rows of other extents
    table = _view_tables(obstacle[:1].cpu().numpy(), [(rows, cols)], side)
    return torch.from_numpy(table).to(grid.device)


def targets_in_view(grid: torch.Tensor, unseen: torch.Tensor, side: int) -> torch.Tensor:
    """(B,H,W) bool: the cells whose side×side view (``side`` odd) holds an ``unseen`` (B,H,W)
    cell. Rows without obstacles take the square (:func:`_square`, bit for bit as before the
    option); rows with obstacles their map's view table, read at its extent."""
    if not reads_obstacles(grid):
        return _square(unseen, side)
    obstacle = grid[:, OBSTACLE_CHANNEL] > 0.5
    has = obstacle.flatten(1).any(dim=1)
    if not has.any():
        return _square(unseen, side)
    rows = torch.nonzero(has).flatten()
    h, w = grid.shape[-2:]
    valid = _one_map_valid(grid, obstacle, side) if has.all() else None
    if valid is None:
        extents = _extent(used_cells(grid[rows]))
        tables = _view_tables(obstacle[rows].cpu().numpy(), extents, side)
        valid = torch.from_numpy(tables).to(grid.device)  # (R,side²,H,W)
    lo, hi = (side - 1) // 2, side // 2
    padded = F.pad(unseen[rows].to(torch.uint8), (lo, hi, lo, hi)).bool()
    seen = torch.zeros((rows.numel(), h, w), dtype=torch.bool, device=grid.device)
    for k, (dy, dx) in enumerate(product(range(side), repeat=2)):  # square_fov_cells' order
        seen |= padded[:, dy : dy + h, dx : dx + w] & valid[:, k]
    out = torch.empty_like(unseen)
    out[rows] = seen
    if not has.all():
        out[~has] = _square(unseen[~has], side)
    return out


def widen_for_obstacle_input(state: dict[str, torch.Tensor], layers: tuple[str, ...]) -> dict:
    """A network's weights without the obstacle channel → with it, giving the very same
    Q-values on maps without obstacles: a zero input channel at
    :data:`~cpp_mujoco.agent.network.OBSTACLE_CHANNEL` of each first convolution ``layers``
    (the network's :attr:`grid_layers`); training then learns to read it."""
    out = dict(state)
    for key in layers:
        weight = state[key]
        zeros = weight.new_zeros((weight.shape[0], 1, *weight.shape[2:]))
        out[key] = torch.cat(
            [weight[:, :OBSTACLE_CHANNEL], zeros, weight[:, OBSTACLE_CHANNEL:]], dim=1
        )
    return out
