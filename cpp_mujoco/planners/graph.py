"""Shortest flight distances on a map, under the safety controller's rules.

Planners reason about reachability and the way home with these tables; they are derived from the
same :class:`SafetyController` the MDP uses, so a planner can never plan a move the MDP rejects.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from cpp_mujoco.grid.coverage import square_fov_masks
from cpp_mujoco.grid.safety import LAND, SafetyController
from cpp_mujoco.maps import GridMap

UNREACHABLE = 10**6


@dataclass(frozen=True, eq=False)
class MapGraph:
    """Per-map tables for planners (cells are flat indices ``row * W + col``).

    ``distance[p, q]``: fewest accepted moves from p to q (UNREACHABLE if none).
    ``home[p]``: fewest actions from p to be landed (moves to a landing cell, plus the land).
    ``fov[p]``: cells seen from p; ``fov_targets[p]``: target cells seen from p.
    """

    grid_map: GridMap
    safety: SafetyController
    distance: np.ndarray
    home: np.ndarray
    fov: np.ndarray
    fov_targets: np.ndarray

    @property
    def num_cells(self) -> int:
        return self.distance.shape[0]


def build_graph(grid_map: GridMap, fov_side: int = 3) -> MapGraph:
    safety = SafetyController(grid_map)
    cells = grid_map.landing.size
    moves = safety.accepted[:, :LAND]
    src = np.repeat(np.arange(cells), LAND)[moves.reshape(-1)]
    dst = safety.next_cell[:, :LAND][moves]
    adjacency = csr_matrix((np.ones(src.size), (src, dst)), shape=(cells, cells))
    dist = shortest_path(adjacency, method="D", unweighted=True)
    distance = np.where(np.isfinite(dist), dist, UNREACHABLE).astype(np.int64)
    landing = np.flatnonzero(grid_map.landing)
    home = distance[:, landing].min(axis=1) + 1
    home = np.minimum(home, UNREACHABLE)
    fov = square_fov_masks(grid_map, fov_side)
    return MapGraph(grid_map, safety, distance, home, fov, fov & grid_map.target.reshape(-1))


@lru_cache(maxsize=16)
def _graph_from_bytes(layers: bytes, shape: tuple[int, ...], fov_side: int) -> MapGraph:
    arr = np.frombuffer(layers, dtype=np.int8).reshape(shape).astype(bool)
    return build_graph(
        GridMap(landing=arr[0], target=arr[1], nfz=arr[2], name="observed"), fov_side
    )


def graph_from_observation(obs: dict[str, np.ndarray], fov_side: int = 3) -> MapGraph:
    """The graph of the map inside a (batched) observation; cached per map."""
    layers = np.asarray(obs["map"])
    if layers.ndim == 4:
        layers = layers[0]
    layers = np.ascontiguousarray(layers, dtype=np.int8)
    return _graph_from_bytes(layers.tobytes(), layers.shape, fov_side)
