"""The arena: the ground plane, the overview camera and the light, with the quadrotor attached.

Only what the physics needs is a model geom: the map's ground tiles and no-fly volumes are drawn
at render time (:mod:`cpp_mujoco.physics.view.scenery`), which makes every ``mj_step`` ~40 %
cheaper on a
16×16 map. A map with obstacles adds their boxes (:mod:`~cpp_mujoco.physics.obstacles`): the
camera's rays meet them and every renderer draws them; a map without gets none, the model it
had before. The map itself is stored in the model (a ``<custom><numeric>`` field the physics never
reads) so a renderer given only the model can still draw it. Cells sit where
:class:`~cpp_mujoco.physics.geometry.GridGeometry` puts them (x east, y north, the map centred on
the origin).
"""

from __future__ import annotations

import math
import os
import warnings

import mujoco

from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.physics.obstacles import OBSTACLE_GROUP, obstacle_boxes
from cpp_mujoco.physics.quadrotor import quadrotor_xml

with warnings.catch_warnings():
    # dm_control picks its own GL backend when imported; with MUJOCO_GL unset it tries GLFW,
    # which warns on a headless machine. We never render through dm_control (rendering picks
    # its backend at the first frame, see physics/view/rendering.py), so that warning says nothing.
    if not os.environ.get("MUJOCO_GL"):
        warnings.filterwarnings("ignore", module="glfw")
    from dm_control import mjcf

__all__ = [
    "SCENERY_NUMERIC", "GridGeometry", "build_arena", "camera_fovy", "compile_arena",
    "scenery_fields", "scenery_numeric",
]  # fmt: skip

SCENERY_NUMERIC = "cpp_mujoco_scenery"  # the model's custom field: H, W, cell, volume height, cells
# MuJoCo 3.17 takes at most 500 numbers in one <numeric> (and 501 crashes the process): the map is
# stored in fields of at most this many, named SCENERY_NUMERIC, then SCENERY_NUMERIC_1, _2, …
NUMERIC_CHUNK = 500


def scenery_fields(values: list[float]) -> list[tuple[str, list[float]]]:
    """(field name, data) of the chunks that hold ``values`` in the model, in order."""
    parts = [values[i : i + NUMERIC_CHUNK] for i in range(0, len(values), NUMERIC_CHUNK)]
    return [(SCENERY_NUMERIC if k == 0 else f"{SCENERY_NUMERIC}_{k}", part)
            for k, part in enumerate(parts)]  # fmt: skip


def scenery_numeric(grid_map: GridMap, cell_size: float, volume_height: float) -> list[float]:
    """What the arena stores in the model so :meth:`Scenery.from_model` can redraw the map:
    H, W, cell size, no-fly volume height, then each cell's ``landing + 2·target + 4·nfz +
    8·obstacle``."""
    codes = grid_map.landing + 2 * grid_map.target.astype(int) + 4 * grid_map.nfz.astype(int)
    codes = codes + 8 * grid_map.obstacle.astype(int)
    return [*grid_map.shape, cell_size, volume_height, *codes.ravel().tolist()]


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

    # the one collision surface and the only world geom (the tiles are render-time scenery)
    margin = 4 * config.cell_size
    arena.worldbody.add(
        "geom", name="ground", type="plane", size=(hx + margin, hy + margin, 0.1),
        rgba=(0.35, 0.35, 0.33, 1), contype=1, conaffinity=1, condim=3,
    )  # fmt: skip
    if grid_map.has_obstacles:
        _add_obstacles(arena, grid_map, config)
    # the map, for the renderer's scenery (physics/view/scenery.py); MuJoCo's physics never reads it
    values = scenery_numeric(grid_map, config.cell_size, 2 * config.altitude)
    for name, data in scenery_fields(values):
        arena.custom.add("numeric", name=name, data=data)
    side = max(hx, hy)
    # MuJoCo sizes the render depth range from the model's extent (znear = 0.01 × extent): without
    # the tiles it would shrink to the quadrotor's size; keep it the map's, as the tiles made it
    arena.statistic.extent = 2 * side
    arena.statistic.center = (0, 0, 0)
    arena.worldbody.add(
        "camera", name="overview", pos=(0, -1.6 * side, 2.2 * side), xyaxes=(1, 0, 0, 0, 0.8, 0.6)
    )

    quad = mjcf.from_path(str(quadrotor_xml()))
    quad.find("camera", "downward").fovy = camera_fovy(config, fov_side)
    frame = arena.worldbody.attach(quad)
    frame.add("freejoint", name="root")
    return arena


def _add_obstacles(arena: mjcf.RootElement, grid_map: GridMap, config: PhysicsConfig) -> None:
    """One box geom per merged block of obstacle cells, without contacts: crashes into them are
    the flight's geometric check (:func:`~cpp_mujoco.physics.obstacles.touching`)."""
    boxes = obstacle_boxes(grid_map, config)
    for k, (pos, size, rgba, building) in enumerate(
        zip(boxes.centers, boxes.half_sizes, boxes.rgba(), boxes.building, strict=True)
    ):
        arena.worldbody.add(
            "geom", name=f"{'building' if building else 'low_obstacle'}_{k}", type="box",
            pos=tuple(pos), size=tuple(size), rgba=tuple(rgba), group=OBSTACLE_GROUP,
            contype=0, conaffinity=0,
        )  # fmt: skip


def compile_arena(arena: mjcf.RootElement) -> mujoco.MjModel:
    """Compile the composed MJCF straight into an ``MjModel``."""
    return mujoco.MjModel.from_xml_string(arena.to_xml_string(), arena.get_assets())
