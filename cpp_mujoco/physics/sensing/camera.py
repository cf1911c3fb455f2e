"""The coverage sensor: the downward camera's footprint on the ground decides what is seen.

No rendering: from the camera pose (``data.cam_xpos``, ``data.cam_xmat``) the four corner rays of
the square image are intersected with the ground plane z = 0, and the cells whose centres lie in
that quadrilateral are seen. A MuJoCo camera looks along its local −z with +y up in the image, so
the corner rays of a square image with half-angle θ are (±tanθ, ±tanθ, −1). A frame tests only a
fixed window of rows and columns around the camera (those whose centres the nominal footprint can
reach), in one compiled kernel for all drones whose frame is due
(:func:`~cpp_mujoco.physics.sensing.kernels.frame`). On a map with obstacles a cell is seen only
if the ray from the camera to its centre meets no obstacle first
(:mod:`~cpp_mujoco.physics.sensing.occlusion`); a map without keeps the kernel above alone.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.physics.obstacles import ObstacleBoxes
from cpp_mujoco.physics.sensing.kernels import corners, frame, frame_near, mark_visible
from cpp_mujoco.physics.sensing.occlusion import BEFORE, RayOcclusion

Polygon = list[tuple[float, float]]


def corner_rays(fovy_deg: float) -> list[tuple[float, float, float]]:
    """Corner ray directions in the camera frame, counter-clockwise in the image."""
    t = math.tan(math.radians(fovy_deg) / 2)
    return [(-t, -t, -1.0), (t, -t, -1.0), (t, t, -1.0), (-t, t, -1.0)]


class CoverageCamera:
    """The downward camera of n drones as a coverage sensor: each frame marks the cells it sees
    in the drone's ``coverage`` row (the env's, shared) and counts the new target cells.

    A cell is seen when its centre lies in the footprint *and* within the nominal (level, cruise
    altitude) footprint around the camera's nadir point; frames more than
    ``config.max_frame_tilt_deg`` off nadir, or with the horizon in view, see nothing (why:
    ``PhysicsConfig``). Frames are due every ``1 / config.camera_rate`` s (:attr:`next_frame`).

    ``cam_xpos`` (n, ncam, 3), ``cam_xmat`` (n, ncam, 9) and ``clock`` (n,) are live arrays of
    the drones' camera poses and times (the batch's bound fields: the pose MuJoCo computed in
    each drone's last step). ``obstacles``: the map's boxes (None: none, nothing occludes);
    ``body``: the quadrotor's body, which the rays leave out."""

    def __init__(
        self,
        model: mujoco.MjModel,
        cam_xpos: np.ndarray,
        cam_xmat: np.ndarray,
        clock: np.ndarray,
        geo: GridGeometry,
        config: PhysicsConfig,
        target: np.ndarray,
        coverage: np.ndarray,
        camera: str = "quadrotor/downward",
        min_down: float = 0.05,
        obstacles: ObstacleBoxes | None = None,
        body: int = -1,
    ):
        self.cam_id = cam = int(model.camera(camera).id)
        fovy = float(model.cam_fovy[cam])
        self.rays = np.array(corner_rays(fovy))  # (4, 3)
        self.cam_xpos, self.cam_xmat, self.clock = cam_xpos[:, cam], cam_xmat[:, cam], clock
        self.period = 1.0 / config.camera_rate
        self.cos_max_tilt = math.cos(math.radians(config.max_frame_tilt_deg))
        self.nominal_half = config.altitude * math.tan(math.radians(fovy) / 2) + 1e-6
        centers = geo.centers()
        self.target = np.asarray(target, dtype=bool).reshape(-1)
        self.coverage = coverage
        self.min_down = min_down
        self.next_frame = np.zeros(len(clock))
        # the window: centres within ±half of a point span at most 2·half/cell + 1 rows or
        # columns; one more (and the eps) absorbs the rounding of where the block starts
        span = math.floor(2 * self.nominal_half / geo.cell_size + 2e-6) + 2
        self._kr, self._kc = min(span, geo.height), min(span, geo.width)
        # a centre's x depends on its column only, y on its row: the same doubles as centers()
        self._x_of_col = centers[: geo.width, 0].copy()
        self._y_of_row = centers[:: geo.width, 1].copy()
        self._constants = np.array([
            self.cos_max_tilt, min_down, self.nominal_half, 1.0 / geo.cell_size, geo.height,
            geo.width, self._kr, self._kc,
        ], dtype=float)  # fmt: skip
        self.occlusion: RayOcclusion | None = None
        if obstacles is not None and len(obstacles):
            n, k = len(clock), self._kr * self._kc
            self.occlusion = RayOcclusion(model, body, n, k)
            self._box_lo, self._box_hi = obstacles.lo, obstacles.hi
            self._cells = np.zeros((n, k), dtype=np.int64)
            self._counts = np.zeros(n, dtype=np.int64)
            self._rays_to = np.zeros((n, k, 3))

    def reset(self, i: int) -> None:
        self.next_frame[i] = 0.0

    def capture(self, drones: np.ndarray) -> np.ndarray:
        """A frame of each of ``drones`` now; how many target cells each saw first."""
        drones = np.asarray(drones, dtype=np.int64)
        self.next_frame[drones] = self.clock[drones] + self.period
        newly = np.zeros(drones.size, dtype=np.int64)
        if self.occlusion is None:
            frame(drones, self.cam_xpos, self.cam_xmat, self.rays, self._constants,
                  self._x_of_col, self._y_of_row, self.target, self.coverage, newly)  # fmt: skip
            return newly
        m, occ = drones.size, self.occlusion
        cells, counts, rays_to = self._cells[:m], self._counts[:m], self._rays_to[:m]
        frame_near(drones, self.cam_xpos, self.cam_xmat, self.rays, self._constants,
                   self._x_of_col, self._y_of_row, self.target, self.coverage, newly,
                   self._box_lo, self._box_hi, cells, counts, rays_to)  # fmt: skip
        near = np.flatnonzero(counts).tolist()
        if near:
            for j in near:
                occ.cast(j, self.cam_xpos[drones[j]], rays_to[j], int(counts[j]))
            mark_visible(drones, counts, cells, occ.geom, occ.dist, BEFORE, self.target,
                         self.coverage, newly)  # fmt: skip
        return newly

    def footprint(self, i: int) -> Polygon | None:
        """Ground corners of drone ``i``'s image now, counter-clockwise (None: the camera is
        below ground or the horizon is in view)."""
        pos, xs, ys = self.cam_xpos[i], np.empty(4), np.empty(4)
        if not pos[2] > 0.0 or not corners(
            *pos, self.cam_xmat[i], self.rays, self.min_down, xs, ys
        ):
            return None
        return list(zip(xs.tolist(), ys.tolist(), strict=True))
