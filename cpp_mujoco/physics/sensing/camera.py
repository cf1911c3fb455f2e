"""The coverage sensor: the downward camera's footprint on the ground decides what is seen.

No rendering: from the camera pose (``data.cam_xpos``, ``data.cam_xmat``) the four corner rays of
the square image are intersected with the ground plane z = 0, and the cells whose centres lie in
that quadrilateral are seen (:class:`CoverageCamera`, owned by the flight). A MuJoCo camera looks
along its local −z with +y up in the image, so the corner rays of a square image with half-angle θ
are (±tanθ, ±tanθ, −1).

Written in scalars: the polygon has four corners and only the ~10–20 cells under its bounding box
are tested, where numpy's per-call overhead would cost more than the arithmetic.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from cpp_mujoco.grid.coverage import mark_seen
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry

Polygon = list[tuple[float, float]]


def corner_rays(fovy_deg: float) -> list[tuple[float, float, float]]:
    """Corner ray directions in the camera frame, counter-clockwise in the image."""
    t = math.tan(math.radians(fovy_deg) / 2)
    return [(-t, -t, -1.0), (t, -t, -1.0), (t, t, -1.0), (-t, t, -1.0)]


def footprint(cam_pos, cam_mat, rays, min_down: float = 0.05) -> Polygon | None:
    """Ground-plane (z = 0) corners of the image, or None when the camera is below ground or a
    corner ray points less than ``min_down`` downwards (the horizon is in view: such a frame is
    not used for mapping).

    ``cam_mat`` is the camera→world rotation, row-major (``data.cam_xmat[i]``).
    """
    px, py, pz = cam_pos[0], cam_pos[1], cam_pos[2]
    if pz <= 0.0:
        return None
    m0, m1, m2, m3, m4, m5, m6, m7, m8 = cam_mat
    corners = []
    for rx, ry, rz in rays:
        down = -(m6 * rx + m7 * ry + m8 * rz)
        if down < min_down:
            return None
        t = pz / down
        corners.append(
            (px + t * (m0 * rx + m1 * ry + m2 * rz), py + t * (m3 * rx + m4 * ry + m5 * rz))
        )
    return corners


def inside_polygon(polygon: Polygon, x: float, y: float) -> bool:
    """Whether (x, y) lies inside the convex ``polygon`` (either winding, boundary included)."""
    pos = neg = False
    ax, ay = polygon[-1]
    for bx, by in polygon:
        cross = (bx - ax) * (y - ay) - (by - ay) * (x - ax)
        pos |= cross > 0.0
        neg |= cross < 0.0
        ax, ay = bx, by
    return not (pos and neg)


def cells_in_footprint(polygon: Polygon, geo: GridGeometry) -> list[int]:
    """Flat indices (``row·W + col``) of the grid cells whose centres lie in ``polygon``."""
    xs = [p[0] for p in polygon]
    ys = [p[1] for p in polygon]
    rows, cols = geo.centred_in(min(xs), max(xs), min(ys), max(ys))
    center, w = geo.cell_center, geo.width
    found = []
    for r in rows:
        for c in cols:
            if inside_polygon(polygon, *center(r, c)):
                found.append(r * w + c)
    return found


class CoverageCamera:
    """The downward camera as a coverage sensor: each :meth:`capture` marks the target cells it
    sees in ``coverage`` (the env's (1, H·W) coverage row, shared) and counts the new ones.

    A cell is seen when its centre lies in the footprint *and* within the nominal (level, cruise
    altitude) footprint around the camera's nadir point; frames more than
    ``config.max_frame_tilt_deg`` off nadir, or with the horizon in view, see nothing (why:
    ``PhysicsConfig``). Frames are due every ``1 / config.camera_rate`` s (:attr:`next_frame`).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        geo: GridGeometry,
        config: PhysicsConfig,
        target: np.ndarray,
        coverage: np.ndarray,
        camera: str = "quadrotor/downward",
    ):
        self.cam_id = int(model.camera(camera).id)
        fovy = math.radians(float(model.cam_fovy[self.cam_id]))
        self.rays = corner_rays(float(model.cam_fovy[self.cam_id]))
        self._pos, self._mat = data.cam_xpos[self.cam_id], data.cam_xmat[self.cam_id]
        self.geo = geo
        self.period = 1.0 / config.camera_rate
        self.cos_max_tilt = math.cos(math.radians(config.max_frame_tilt_deg))
        self.nominal_half = config.altitude * math.tan(fovy / 2) + 1e-6  # level footprint, m
        self._centers = [tuple(c) for c in geo.centers().tolist()]
        self.target = target.reshape(-1)
        self.coverage = coverage
        self._seen = np.zeros((1, self.target.size), dtype=bool)
        self.reset()

    def reset(self) -> None:
        """A new episode: a frame is due at once."""
        self.next_frame = 0.0
        self.frames = 0
        self.last_footprint: Polygon | None = None

    def capture(self, time: float) -> int:
        """Take a frame at simulated ``time``; return how many target cells it saw first."""
        self.next_frame = time + self.period
        self.frames += 1
        pos, mat = self._pos.tolist(), self._mat.tolist()
        poly = footprint(pos, mat, self.rays)
        self.last_footprint = poly
        if poly is None or mat[8] < self.cos_max_tilt:  # camera −z vs world −z
            return 0
        x, y, half, centers = pos[0], pos[1], self.nominal_half, self._centers
        cells = [
            c
            for c in cells_in_footprint(poly, self.geo)
            if abs(centers[c][0] - x) <= half and abs(centers[c][1] - y) <= half
        ]
        if not cells:
            return 0
        seen = self._seen
        seen[:] = False
        seen[0, cells] = True
        return int(mark_seen(self.coverage, seen, self.target)[0])
