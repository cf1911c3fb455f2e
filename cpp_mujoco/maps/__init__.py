"""Grid maps: the PNG format (:mod:`~cpp_mujoco.maps.format`), their symmetries
(:mod:`~cpp_mujoco.maps.symmetry`) and where a named map comes from
(:mod:`~cpp_mujoco.maps.load`)."""

from cpp_mujoco.maps.format import LAYERS, MAX_SIDE, GridMap, MapError, bundled_maps
from cpp_mujoco.maps.load import load_map

__all__ = ["LAYERS", "MAX_SIDE", "GridMap", "MapError", "bundled_maps", "load_map"]
