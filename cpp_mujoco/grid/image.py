"""A map, its coverage and the UAV as an RGB image (the paper's Fig. 2 colours), in plain numpy."""

from __future__ import annotations

import numpy as np

from cpp_mujoco.maps import GridMap

# The paper's palette: red no-fly, green target, blue landing, yellow target + no-fly; the
# obstacles in greys: a building (obstacle + no-fly) dark, a low obstacle light.
COLORS = {
    "empty": (235, 235, 235),
    "nfz": (200, 40, 40),
    "target": (40, 160, 60),
    "landing": (40, 80, 200),
    "yellow": (230, 200, 30),
    "building": (90, 90, 100),
    "low obstacle": (160, 160, 170),
    "uav": (20, 20, 20),
}


def zone_colors(grid_map: GridMap) -> np.ndarray:
    """(H, W, 3) uint8 colour of each cell's zone."""
    img = np.empty((*grid_map.shape, 3), dtype=np.uint8)
    img[:] = COLORS["empty"]
    img[grid_map.landing] = COLORS["landing"]
    img[grid_map.target] = COLORS["target"]
    img[grid_map.nfz] = COLORS["nfz"]
    img[grid_map.target & grid_map.nfz] = COLORS["yellow"]
    img[grid_map.obstacle & ~grid_map.nfz] = COLORS["low obstacle"]
    img[grid_map.obstacle & grid_map.nfz] = COLORS["building"]
    return img


def grid_image(
    grid_map: GridMap, coverage: np.ndarray, position: int, scale: int = 16
) -> np.ndarray:
    """Zones, seen cells lightened, the UAV's cell dark; each cell ``scale`` pixels wide."""
    img = zone_colors(grid_map).astype(np.float32)
    seen = np.asarray(coverage, dtype=bool).reshape(grid_map.shape)
    img[seen] = 0.45 * img[seen] + 0.55 * 255
    row, col = divmod(int(position), grid_map.shape[1])
    img[row, col] = COLORS["uav"]
    return np.kron(img.astype(np.uint8), np.ones((scale, scale, 1), dtype=np.uint8))
