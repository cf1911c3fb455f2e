"""The map's obstacles as boxes in the world: where they stand, how high, and what hits them.

A building (an obstacle that is also no-fly) rises ``building_height_m`` above the ground, above
the cruise altitude: it blocks flight and view. A low obstacle rises ``low_obstacle_height_m``,
below the cruise altitude: a drone flies over it, the camera does not see through it. Cells of
one kind are merged into rectangles (:func:`rectangles`): a block of buildings is one box, not
one per cell, so the arena's kinematics, the camera's rays and the crash check each loop over a
handful of boxes (map-sized blocks of obstacle cells would otherwise cost what the ground tiles
cost as geoms, ``physics/view/scenery.py``).

The boxes are arena geoms for the camera's rays and the renderers, but take no part in MuJoCo's
contacts: a drone touching one is a crash, decided geometrically every control tick
(:func:`touching`, the airframe's bounding sphere against each box). Why not contacts: airborne
drones step on a contact-free copy of the model (:mod:`~cpp_mujoco.physics.airborne`), which
would let them fly through a building; collidable boxes would instead raise that copy's floor to
the roof, and no drone would be airborne any more. The geometric check holds on either model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry

__all__ = [
    "BUILDING_RGBA", "LOW_OBSTACLE_RGBA", "OBSTACLE_FAILURES", "OBSTACLE_GROUP", "ObstacleBoxes",
    "obstacle_boxes", "rectangles", "touching",
]  # fmt: skip

BUILDING_RGBA = (0.55, 0.50, 0.46, 1.0)  # concrete: apart from every zone colour and the sky
LOW_OBSTACLE_RGBA = (0.45, 0.30, 0.16, 1.0)  # dark brown: a shed, a tree line
# the geom group of the boxes: the ground is group 0 and the quadrotor group 2, so a ray cast
# with only this group enabled meets obstacles and nothing else; group 1 renders by default
OBSTACLE_GROUP = 1
# the crash reasons, by kind (index 0: building, 1: low obstacle)
OBSTACLE_FAILURES = ("hit a building", "hit a low obstacle")


@dataclass(frozen=True)
class ObstacleBoxes:
    """K axis-aligned boxes standing on the ground: (K, 3) ``centers`` and ``half_sizes`` (m,
    world frame), (K,) ``building`` (else a low obstacle) and (K, 4) ``cells`` (first row, last
    row, first column, last column of the map cells each covers)."""

    centers: np.ndarray
    half_sizes: np.ndarray
    building: np.ndarray
    cells: np.ndarray

    def __len__(self) -> int:
        return len(self.building)

    @property
    def lo(self) -> np.ndarray:
        """(K, 3) lowest corner of each box."""
        return self.centers - self.half_sizes

    @property
    def hi(self) -> np.ndarray:
        """(K, 3) highest corner of each box."""
        return self.centers + self.half_sizes

    def rgba(self) -> np.ndarray:
        """(K, 4) each box's colour: a building's or a low obstacle's."""
        return np.where(self.building[:, None], BUILDING_RGBA, LOW_OBSTACLE_RGBA)


def rectangles(mask: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Cover the True cells of a 2-D mask with disjoint rectangles (r0, r1, c0, c1), inclusive:
    each row's runs, a run carried down while the next row has the very same run. Exact (the
    union is the mask) and deterministic; not the fewest rectangles, but one per block."""
    mask = np.asarray(mask, dtype=bool)
    done: list[tuple[int, int, int, int]] = []
    open_: dict[tuple[int, int], int] = {}  # (c0, c1) → the row its rectangle began
    for r in range(mask.shape[0] + 1):
        row = mask[r] if r < mask.shape[0] else np.zeros(mask.shape[1], dtype=bool)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], row.astype(np.int8), [0]])))
        runs = {(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)}
        for run in [k for k in open_ if k not in runs]:
            done.append((open_.pop(run), r - 1, *run))
        for run in runs - open_.keys():
            open_[run] = r
    return sorted(done)


def obstacle_boxes(grid_map: GridMap, config: PhysicsConfig) -> ObstacleBoxes:
    """The boxes of ``grid_map``'s obstacles at ``config``'s cell size and heights: buildings
    first, then low obstacles, each kind in :func:`rectangles`' order. ``ValueError`` for
    heights that contradict their kind (:meth:`PhysicsConfig.check_obstacle_heights`)."""
    config.check_obstacle_heights()
    geo = GridGeometry.of(grid_map, config.cell_size)
    cs = config.cell_size
    centers, halves, kinds, cells = [], [], [], []
    buildings = grid_map.obstacle & grid_map.nfz
    for building, mask, height in (
        (True, buildings, config.building_height_m),
        (False, grid_map.obstacle & ~grid_map.nfz, config.low_obstacle_height_m),
    ):
        for r0, r1, c0, c1 in rectangles(mask):
            x, y = geo.cell_center((r0 + r1) / 2, (c0 + c1) / 2)
            centers.append((x, y, height / 2))
            halves.append(((c1 - c0 + 1) * cs / 2, (r1 - r0 + 1) * cs / 2, height / 2))
            kinds.append(building)
            cells.append((r0, r1, c0, c1))
    return ObstacleBoxes(
        np.array(centers, dtype=float).reshape(-1, 3),
        np.array(halves, dtype=float).reshape(-1, 3),
        np.array(kinds, dtype=bool),
        np.array(cells, dtype=np.int64).reshape(-1, 4),
    )


@njit(cache=True)
def touching(drones, pos, lo, hi, radius, out):
    """``out[j]``: the first box (K boxes: corners ``lo``, ``hi``) that a sphere of ``radius``
    around drone ``drones[j]``'s position ``pos[d]`` reaches, or -1; returns how many reach one.
    A position with a NaN reaches nothing (the flight's divergence check has it)."""
    hits = 0
    r2 = radius * radius
    for j in range(drones.size):
        d = drones[j]
        out[j] = -1
        if not math.isfinite(pos[d, 0] + pos[d, 1] + pos[d, 2]):
            continue
        for b in range(lo.shape[0]):
            gap2 = 0.0
            for a in range(3):
                p = pos[d, a]
                g = max(lo[b, a] - p, p - hi[b, a], 0.0)
                gap2 += g * g
            if gap2 < r2:
                out[j] = b
                hits += 1
                break
    return hits


class ObstacleCrashes:
    """The flight's per-tick obstacle check: a drone whose airframe (a sphere of ``radius``
    around its body origin) reaches a box fails with :data:`OBSTACLE_FAILURES`' reason and
    leaves the action. ``n``: the drones of the batch."""

    def __init__(self, boxes: ObstacleBoxes, radius: float, n: int):
        self.lo, self.hi, self.radius = boxes.lo, boxes.hi, float(radius)
        self.reason = [OBSTACLE_FAILURES[0 if b else 1] for b in boxes.building.tolist()]
        self._out = np.zeros(n, dtype=np.int64)

    def __call__(
        self, drones: np.ndarray, pos: np.ndarray, failure: np.ndarray, flying: np.ndarray
    ) -> np.ndarray:
        """Those of ``drones`` (positions ``pos``, (n, 3)) that touch no box; the others get
        their ``failure`` reason and leave ``flying``."""
        out = self._out[: drones.size]
        if not touching(drones, pos, self.lo, self.hi, self.radius, out):
            return drones
        hit = out >= 0
        for d, b in zip(drones[hit].tolist(), out[hit].tolist(), strict=True):
            failure[d], flying[d] = self.reason[b], False
        return drones[~hit]
