"""The map's ground tiles and no-fly volumes, drawn into a rendered scene instead of simulated.

Why not in the physics model: as model geoms (291 of them on a 16×16 map) they cost ~40 % of
every ``mj_step`` — kinematics and the broad-phase run over every geom — although only the ground
plane ever collides. So the model keeps the ground, the camera, the light and the quadrotor, and
:class:`Scenery` appends the tiles and volumes to a :class:`mujoco.MjvScene` after
``update_scene``, once per frame, with the colours and places they had as model geoms.
``decorate(scene, seen)`` draws the cells the camera has seen lighter (the paper's convention),
and a raised kerb around each landing area, so where the UAV may land reads from any view.
Obstacles are model geoms (the camera's rays meet them, :mod:`~cpp_mujoco.physics.obstacles`), so
every renderer draws them, in a building's or a low obstacle's colour; the scenery leaves out the
no-fly volume of a building's cell, which the building's box already fills.

The arena stores the map in the model (a ``<custom><numeric>`` field, which the physics never
reads), so :meth:`Scenery.from_model` redraws it from a compiled model alone. No GL here: the
tiles go into a scene whatever renders it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from cpp_mujoco.physics.arena import SCENERY_NUMERIC
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry

if TYPE_CHECKING:
    from cpp_mujoco.maps import GridMap

__all__ = [
    "KERB_RGBA", "NFZ_VOLUME_RGBA", "TILE_GAP", "ZONE_RGBA", "Scenery", "SceneryError",
    "landing_kerbs", "zone_of",
]  # fmt: skip

# the paper's colours; a landing cell that is also a target shows as landing (blue-green)
ZONE_RGBA = {
    "empty": (0.62, 0.62, 0.60, 1.0),  # mid grey: a seen (lighter) empty cell must show
    "landing": (0.20, 0.35, 0.90, 1.0),
    "target": (0.25, 0.75, 0.30, 1.0),
    "landing_target": (0.15, 0.60, 0.75, 1.0),
    "nfz": (0.85, 0.20, 0.20, 1.0),
    "target_nfz": (0.95, 0.85, 0.20, 1.0),
}
NFZ_VOLUME_RGBA = (1.0, 0.1, 0.1, 0.18)
TILE_GAP = 0.03  # m between tiles, so the grid is visible from above
TILE_HALF_HEIGHT = 0.005  # m; a tile is a thin box lying on the ground plane
SEEN_LIGHTEN = 0.55  # a seen cell's colour moves this far towards white (as grid_image does)
TILE_SPECULAR = 0.05  # matte: a glossy highlight would wash a tile's colour out to white
KERB_RGBA = (1.0, 0.85, 0.15, 1.0)  # the landing areas' outline: yellow on blue, as on helipads
KERB_HALF_WIDTH = 0.08  # m; ~5 px in a 512×384 chase frame
KERB_HALF_HEIGHT = 0.05  # m; raised, so it still reads at grazing angles
_ZONES = tuple(ZONE_RGBA)


class SceneryError(RuntimeError):
    """The scene has no room for the scenery, or a model carries no map to draw."""


def zone_of(grid_map: GridMap, row: int, col: int) -> str:
    """The zone name (a :data:`ZONE_RGBA` key) of one cell."""
    return _ZONES[int(_zone_index(*(layer[row, col] for layer in grid_map.layers)))]


def _zone_index(landing, target, nfz):
    """Index into ``_ZONES`` of each cell; the arguments are booleans or boolean arrays."""
    landing, target, nfz = (np.asarray(a, dtype=bool) for a in (landing, target, nfz))
    lone = np.where(target, _ZONES.index("target"), _ZONES.index("empty"))
    lands = np.where(target, _ZONES.index("landing_target"), _ZONES.index("landing"))
    nofly = np.where(target, _ZONES.index("target_nfz"), _ZONES.index("nfz"))
    return np.where(nfz, nofly, np.where(landing, lands, lone))


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True in a 1-D boolean array."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def landing_kerbs(landing: np.ndarray, geometry: GridGeometry) -> tuple[np.ndarray, np.ndarray]:
    """(K, 3) centres and (K, 3) half sizes of boxes outlining every landing area: one box per
    straight run of border between a landing cell and a non-landing one (or the map's edge), so
    a 6×6 landing block costs 4 geoms, not 36 cells' worth."""
    land = np.pad(np.asarray(landing, dtype=bool), 1)  # the map's edge borders nothing
    h, w, cs = geometry.height, geometry.width, geometry.cell_size
    z, k = KERB_HALF_HEIGHT, KERB_HALF_WIDTH
    pos, size = [], []
    for r in range(h + 1):  # the line between rows r-1 and r, at y = (H/2 - r)·cell
        for a, b in _runs(land[r, 1:-1] != land[r + 1, 1:-1]):
            pos.append(((a + b + 1) / 2 * cs - w / 2 * cs, (h / 2 - r) * cs, z))
            size.append(((b - a + 1) / 2 * cs + k, k, z))
    for c in range(w + 1):  # the line between columns c-1 and c, at x = (c - W/2)·cell
        for a, b in _runs(land[1:-1, c] != land[1:-1, c + 1]):
            pos.append(((c - w / 2) * cs, (h / 2 - (a + b + 1) / 2) * cs, z))
            size.append((k, (b - a + 1) / 2 * cs + k, z))
    return np.array(pos, dtype=float).reshape(-1, 3), np.array(size, dtype=float).reshape(-1, 3)


class Scenery:
    """Ground tiles (every cell, its zone's colour), kerbs round the landing areas and
    translucent no-fly volumes of one map.

    ``config`` is the :class:`PhysicsConfig` (cell size, and no-fly volumes twice the cruise
    altitude high) or a :class:`GridGeometry` (then ``volume_height`` defaults to the default
    config's). Everything is precomputed here; :meth:`decorate` only copies it into the scene.
    """

    def __init__(
        self,
        grid_map: GridMap,
        config: PhysicsConfig | GridGeometry,
        volume_height: float | None = None,
    ):
        if isinstance(config, GridGeometry):
            geometry = config
            if volume_height is None:
                volume_height = 2 * PhysicsConfig().altitude
        else:
            geometry = GridGeometry.of(grid_map, config.cell_size)
            volume_height = 2 * config.altitude if volume_height is None else volume_height
        if geometry.height != grid_map.shape[0] or geometry.width != grid_map.shape[1]:
            raise ValueError(f"geometry {geometry} does not fit a {grid_map.shape} map")
        self._build(
            grid_map.landing, grid_map.target, grid_map.nfz, geometry, volume_height,
            obstacle=grid_map.obstacle,
        )  # fmt: skip

    @classmethod
    def from_model(cls, model: mujoco.MjModel) -> Scenery | None:
        """The scenery of the map an arena model was built from; None for a model without one."""
        try:
            values = np.asarray(model.numeric(SCENERY_NUMERIC).data, dtype=float)
        except KeyError:
            return None
        parts, k = [values], 1
        while True:  # a large map is stored in several fields (physics/arena.py, scenery_fields)
            try:
                parts.append(np.asarray(model.numeric(f"{SCENERY_NUMERIC}_{k}").data, float))
            except KeyError:
                break
            k += 1
        values = np.concatenate(parts)
        h, w = int(values[0]), int(values[1])
        codes = values[4:].astype(int).reshape(h, w)
        self = cls.__new__(cls)
        layers = (codes & 1 > 0, codes & 2 > 0, codes & 4 > 0)
        geometry = GridGeometry(h, w, float(values[2]))
        self._build(*layers, geometry, float(values[3]), obstacle=codes & 8 > 0)
        return self

    def _build(
        self, landing, target, nfz, geometry: GridGeometry, volume_height: float, obstacle=None
    ) -> None:
        self.geometry = geometry
        self.volume_height = volume_height
        xy = geometry.centers()
        n = len(xy)
        rgba = np.array(list(ZONE_RGBA.values()), dtype=np.float32)
        self._tile_rgba = rgba[_zone_index(landing, target, nfz).ravel()]
        self._seen_rgba = self._tile_rgba.copy()
        self._seen_rgba[:, :3] += SEEN_LIGHTEN * (1.0 - self._seen_rgba[:, :3])
        half = geometry.cell_size / 2
        self._tile_pos = np.column_stack([xy, np.full(n, TILE_HALF_HEIGHT)])
        self._tile_size = np.array([half - TILE_GAP / 2, half - TILE_GAP / 2, TILE_HALF_HEIGHT])
        volumes = np.asarray(nfz, dtype=bool)
        if obstacle is not None:  # a building's box stands where its no-fly volume would
            volumes = volumes & ~np.asarray(obstacle, dtype=bool)
        cells = np.flatnonzero(volumes.ravel())
        self._volume_pos = np.column_stack([xy[cells], np.full(len(cells), volume_height / 2)])
        self._volume_size = np.array([half, half, volume_height / 2])
        self._volume_rgba = np.array(NFZ_VOLUME_RGBA, dtype=np.float32)
        self._kerb_pos, self._kerb_size = landing_kerbs(landing, geometry)
        self._kerb_rgba = np.array(KERB_RGBA, dtype=np.float32)
        self._mat = np.eye(3).ravel()
        self._box = int(mujoco.mjtGeom.mjGEOM_BOX)
        self._static = int(mujoco.mjtCatBit.mjCAT_STATIC)
        self._unknown = int(mujoco.mjtObj.mjOBJ_UNKNOWN)
        # per-geom rows as separate arrays: slicing a (N, 3) array per geom per frame costs more
        self._tile_rows = list(self._tile_pos)
        self._volume_rows = list(self._volume_pos)
        self._kerb_rows = list(zip(self._kerb_pos, self._kerb_size, strict=True))

    @property
    def geom_count(self) -> int:
        """Geoms one :meth:`decorate` adds (a renderer's scene needs room for them)."""
        return len(self._tile_rows) + len(self._kerb_rows) + len(self._volume_rows)

    def tiles(self, seen: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N, 3) centres, (3,) half sizes and (N, 4) colours of the tiles, flat cell order."""
        return self._tile_pos, self._tile_size, self._colours(seen)

    def kerbs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(K, 3) centres, (K, 3) half sizes and (4,) colour of the landing areas' outline."""
        return self._kerb_pos, self._kerb_size, self._kerb_rgba

    def volumes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(M, 3) centres, (3,) half sizes and (4,) colour of the no-fly volumes."""
        return self._volume_pos, self._volume_size, self._volume_rgba

    def _colours(self, seen: np.ndarray | None) -> np.ndarray:
        if seen is None:
            return self._tile_rgba
        mask = np.asarray(seen, dtype=bool).reshape(-1)
        if mask.shape != (len(self._tile_rgba),):
            raise ValueError(f"seen has {mask.size} cells, the map {len(self._tile_rgba)}")
        return np.where(mask[:, None], self._seen_rgba, self._tile_rgba)

    def decorate(self, scene: mujoco.MjvScene, seen: np.ndarray | None = None) -> None:
        """Append the tiles (``seen`` cells, (H, W) or flat, lighter), the landing kerbs and the
        no-fly volumes to ``scene``; call after ``update_scene`` and before rendering.
        :class:`SceneryError` if the scene has no room for them (``maxgeom``), rather than a map
        drawn in part."""
        colours = list(self._colours(seen))
        start = scene.ngeom
        if start + self.geom_count > scene.maxgeom:
            raise SceneryError(
                f"the scene holds {scene.maxgeom} geoms, {start} used: no room for the map's "
                f"{self.geom_count}; make the renderer with max_geom >= {start + self.geom_count}"
            )
        init, geoms, box, mat = mujoco.mjv_initGeom, scene.geoms, self._box, self._mat
        items = [(p, self._tile_size, c) for p, c in zip(self._tile_rows, colours, strict=True)]
        items += [(p, size, self._kerb_rgba) for p, size in self._kerb_rows]
        items += [(p, self._volume_size, self._volume_rgba) for p in self._volume_rows]
        for i, (pos, size, rgba) in enumerate(items, start):
            geom = geoms[i]
            init(geom, box, size, pos, mat, rgba)
            geom.specular = TILE_SPECULAR
            geom.category, geom.objtype, geom.objid, geom.segid = (
                self._static, self._unknown, -1, i,
            )  # fmt: skip
        scene.ngeom = start + len(items)

    def __call__(self, scene: mujoco.MjvScene, data: mujoco.MjData | None = None) -> None:
        """The scenery as :class:`~cpp_mujoco.physics.view.rendering.OffscreenCamera`'s decorator
        (the map as it is, nothing seen; :class:`~cpp_mujoco.physics.view.chase.MissionDecor` adds
        the live coverage)."""
        self.decorate(scene)
