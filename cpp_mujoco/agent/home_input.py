"""The general network's "moves home" input: fewest moves from the UAV's cell to a landing cell.

Why: the safe greedy planner lands every episode because it knows this number
(:attr:`~cpp_mujoco.grid.graph.MapGraph.home`); a network that must read it off the pixels of a
map it has never seen plateaued at 55–76 % landing on 32×32 validation maps. The number is a
property of the map, so it is computed once per map — :func:`~cpp_mujoco.grid.graph.build_graph`'s
own search over the safety controller's accepted moves, the table the planners use — and each
state only gathers its UAV's cell from it:

* :func:`home_field` caches the fields by the map's cells (any observation: a policy flying a map
  it has never seen, the trainer's acting batch of many maps);
* :meth:`MapPool.moves_home <cpp_mujoco.agent.map_pool.MapPool.moves_home>` keeps them by pool
  index for the replay's minibatches, filled from :func:`home_field` (the same numbers).

A pool map is padded with no-fly cells; no move enters them, so the padded map's field equals the
map's own on its cells, and a state has the same input padded or not.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from cpp_mujoco.grid.actions import NUM_ACTIONS
from cpp_mujoco.grid.graph import build_graph
from cpp_mujoco.grid.return_rule import paid_actions
from cpp_mujoco.grid.way_home import ReturnMargin
from cpp_mujoco.maps import MAX_SIDE, GridMap

# the moves of a cell with no way home. Never the UAV's: it starts on a landing cell and flies
# only accepted moves, which can all be flown back; larger than any way home on any map
NO_WAY_HOME = MAX_SIDE * MAX_SIDE
# fields kept: a 32×32 one is 4 kB (plus its 3 kB key), so every map of a 1,024-map pool fits
CACHE_MAPS = 2048


@lru_cache(maxsize=CACHE_MAPS)
def _tables(cells: bytes, shape: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """(moves home per cell, (H·W, 5) actions home after each action) of one map's cells."""
    landing, target, nfz = np.frombuffer(cells, dtype=bool).reshape(shape)
    h, w = shape[1:]
    if not landing.any():
        field = np.full(h * w, NO_WAY_HOME, dtype=np.int32)
        after = np.full((h * w, NUM_ACTIONS), NO_WAY_HOME + 1, dtype=np.int32)
    else:  # targets do not change a move (GridMap wants one); a landing cell is never no-fly
        grid_map = GridMap(
            landing=landing, target=target if target.any() else landing, nfz=nfz & ~landing,
            name="observed",
        )  # fmt: skip
        graph = build_graph(grid_map)
        field = np.minimum(graph.home - 1, NO_WAY_HOME).astype(np.int32)
        after = np.minimum(graph.home_after, NO_WAY_HOME + 1).astype(np.int32)
    field.flags.writeable = after.flags.writeable = False
    return field, after


def _map_cells(layers: np.ndarray) -> np.ndarray:
    cells = np.ascontiguousarray(np.asarray(layers) != 0)
    if cells.ndim != 3 or cells.shape[0] != 3:
        raise ValueError(f"a map is (3, H, W) layers, got shape {cells.shape}")
    return cells


def home_field(layers: np.ndarray) -> np.ndarray:
    """(H·W,) int32, read-only: fewest accepted moves from each cell of a (3,H,W) map (landing,
    target, no-fly; any dtype, nonzero = set) to its nearest landing cell — 0 on one,
    :data:`NO_WAY_HOME` where there is no way. Cached by the map's cells."""
    cells = _map_cells(layers)
    return _tables(cells.tobytes(), cells.shape)[0]


def home_after(layers: np.ndarray) -> np.ndarray:
    """(H·W, 5) int32, read-only: :attr:`MapGraph.home_after <cpp_mujoco.grid.graph.MapGraph.
    home_after>` of a (3,H,W) map — the actions still needed to be landed after each action in
    each cell — capped above :data:`NO_WAY_HOME`. Cached with :func:`home_field`."""
    cells = _map_cells(layers)
    return _tables(cells.tobytes(), cells.shape)[1]


def _at_cells(maps: np.ndarray, position: np.ndarray, table: int) -> np.ndarray:
    """Row i's map's :func:`_tables` entry ``table`` (0: moves home, 1: actions home after each
    action) at row i's UAV cell. ``maps``: one (3,H,W) map shared by the batch or (N,3,H,W), one
    per row; ``position``: the (N,H,W) one-hot UAV cells. One cached table per distinct map,
    then a gather: the per-row work is a cache lookup of the row's map, never a loop over
    cells."""
    position = np.asarray(position)
    n = position.shape[0]
    cell = position.reshape(n, int(np.prod(position.shape[1:]))).argmax(axis=1)
    maps = np.asarray(maps)
    if maps.ndim == 4 and n and maps.strides[0] == 0:  # GridMDP's broadcast view of one map
        maps = maps[0]
    if maps.ndim == 3:
        cells = _map_cells(maps)
        return _tables(cells.tobytes(), cells.shape)[table][cell]
    if maps.shape[0] != n:
        raise ValueError(f"{maps.shape[0]} maps for {n} positions")
    cells = np.ascontiguousarray(maps != 0)
    shape = cells.shape[1:]
    rows = [
        _tables(layers.tobytes(), shape)[table][c] for layers, c in zip(cells, cell, strict=True)
    ]
    return np.array(rows, dtype=np.int32).reshape(n, *((NUM_ACTIONS,) if table else ()))


def moves_home(maps: np.ndarray, position: np.ndarray) -> np.ndarray:
    """(N,) int32: each state's moves home (:func:`_at_cells`: ``maps`` shared or per row,
    ``position`` one-hot)."""
    return _at_cells(maps, position, 0)


def safe_actions(
    maps: np.ndarray,
    position: np.ndarray,
    budget: np.ndarray,
    wind: np.ndarray | None = None,
    margin: ReturnMargin | None = None,
) -> np.ndarray:
    """(N, 5) bool: the return rule (:func:`~cpp_mujoco.grid.return_rule.paid_actions`) for a
    batch of observations — ``maps`` one (3,H,W) map shared by the batch or (N,3,H,W) per row,
    ``position`` the (N,H,W) one-hot cells, ``budget`` (N,) or (N,1) the remaining budget,
    ``wind`` (N,2) the observed wind (None: calm air) and ``margin`` the wind planners'."""
    return paid_actions(_at_cells(maps, position, 1), budget, wind, margin)
