"""The arena: ground tiles and no-fly volumes built from a grid map, with the quadrotor attached.

Cells sit where :class:`~cpp_mujoco.physics.geometry.GridGeometry` puts them (x east, y north,
the map centred on the origin).
"""

from __future__ import annotations

import math
import os
import warnings

import mujoco

from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.physics.quadrotor import quadrotor_xml

with warnings.catch_warnings():
    # dm_control picks its own GL backend when imported; with MUJOCO_GL unset it tries GLFW,
    # which warns on a headless machine. We never render through dm_control (rendering picks
    # its backend at the first frame, see review/rendering.py), so that warning says nothing.
    if not os.environ.get("MUJOCO_GL"):
        warnings.filterwarnings("ignore", module="glfw")
    from dm_control import mjcf

__all__ = ["GridGeometry", "build_arena", "camera_fovy", "compile_arena", "zone_of"]

# the paper's colours; a landing cell that is also a target shows as landing (blue-green)
ZONE_RGBA = {
    "empty": (0.80, 0.80, 0.78, 1.0),
    "landing": (0.20, 0.35, 0.90, 1.0),
    "target": (0.25, 0.75, 0.30, 1.0),
    "landing_target": (0.15, 0.60, 0.75, 1.0),
    "nfz": (0.85, 0.20, 0.20, 1.0),
    "target_nfz": (0.95, 0.85, 0.20, 1.0),
}
NFZ_VOLUME_RGBA = (1.0, 0.1, 0.1, 0.18)
TILE_GAP = 0.03  # m between tiles, so the grid is visible from above


def zone_of(grid_map: GridMap, row: int, col: int) -> str:
    landing, target, nfz = (bool(layer[row, col]) for layer in grid_map.layers)
    if nfz:
        return "target_nfz" if target else "nfz"
    if landing:
        return "landing_target" if target else "landing"
    return "target" if target else "empty"


def camera_fovy(config: PhysicsConfig, fov_side: int = 3) -> float:
    """Vertical field of view (deg, square image) whose footprint, hovering level at cruise
    altitude over a cell centre, spans exactly ``fov_side`` × ``fov_side`` cells."""
    return math.degrees(2 * math.atan(fov_side * config.cell_size / 2 / config.altitude))


def build_arena(grid_map: GridMap, config: PhysicsConfig, fov_side: int = 3) -> mjcf.RootElement:
    """The MJCF model of the map with the quadrotor attached on a free joint."""
    geo = GridGeometry.of(grid_map, config.cell_size)
    hx, hy = geo.half_extent
    arena = mjcf.RootElement(model=f"arena_{grid_map.name}")
    arena.option.timestep = config.timestep
    arena.option.density = 0.0  # drag is our own model (wind.py), not MuJoCo's fluid forces
    arena.visual.headlight.ambient = (0.4, 0.4, 0.4)
    arena.visual.map.zfar = 500.0
    arena.visual.__getattr__("global").offwidth = 1280
    arena.visual.__getattr__("global").offheight = 720
    arena.worldbody.add("light", pos=(0, 0, 50), dir=(0, 0, -1), directional=True)

    # the one collision surface; tiles above it are visual only
    margin = 4 * config.cell_size
    arena.worldbody.add(
        "geom", name="ground", type="plane", size=(hx + margin, hy + margin, 0.1),
        rgba=(0.35, 0.35, 0.33, 1), contype=1, conaffinity=1, condim=3,
    )  # fmt: skip
    tile = config.cell_size / 2 - TILE_GAP / 2
    volume_height = 2 * config.altitude
    for row in range(geo.height):
        for col in range(geo.width):
            x, y = geo.cell_center(row, col)
            zone = zone_of(grid_map, row, col)
            arena.worldbody.add(
                "geom", name=f"tile_{row}_{col}", type="box", size=(tile, tile, 0.005),
                pos=(x, y, 0.005), rgba=ZONE_RGBA[zone], contype=0, conaffinity=0, group=0,
            )  # fmt: skip
            if grid_map.nfz[row, col]:
                arena.worldbody.add(
                    "geom", name=f"nfz_{row}_{col}", type="box",
                    size=(config.cell_size / 2, config.cell_size / 2, volume_height / 2),
                    pos=(x, y, volume_height / 2), rgba=NFZ_VOLUME_RGBA,
                    contype=0, conaffinity=0, group=1,
                )  # fmt: skip
    side = max(hx, hy)
    arena.worldbody.add(
        "camera", name="overview", pos=(0, -1.6 * side, 2.2 * side), xyaxes=(1, 0, 0, 0, 0.8, 0.6)
    )

    quad = mjcf.from_path(str(quadrotor_xml()))
    quad.find("camera", "downward").fovy = camera_fovy(config, fov_side)
    frame = arena.worldbody.attach(quad)
    frame.add("freejoint", name="root")
    return arena


def compile_arena(arena: mjcf.RootElement) -> mujoco.MjModel:
    """Compile the composed MJCF straight into an ``MjModel``."""
    return mujoco.MjModel.from_xml_string(arena.to_xml_string(), arena.get_assets())
