"""The coverage camera of N drones at once: :class:`~cpp_mujoco.physics.camera.CoverageCamera`'s
rule as arrays.

The scalar camera tests the ~10–20 cells under a footprint's bounding box one by one; for a batch
the same tests run over every cell of the map for all due drones together (a few thousand
elements per numpy call instead of a Python loop per cell). The tests are the scalar ones, in the
same floating-point order — the same candidate rows and columns (``GridGeometry.centred_in``),
the same cross products (``inside_polygon``), the same nominal-footprint bound — so a drone of
the batch sees exactly the cells its single flight sees.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from cpp_mujoco.grid.coverage import mark_seen
from cpp_mujoco.physics.camera import corner_rays
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry


class BatchedCamera:
    """Frames of the downward camera of n drones; marks the (n, H·W) ``coverage`` rows and
    counts newly seen target cells. ``cam_xpos`` (n, ncam, 3), ``cam_xmat`` (n, ncam, 9) and
    ``clock`` (n,) are live arrays of the drones' camera poses and times (the batch's bound
    fields: the pose MuJoCo computed in each drone's last step, as a single flight reads it
    from its ``MjData``)."""

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
    ):
        cam = int(model.camera(camera).id)
        fovy = float(model.cam_fovy[cam])
        self.rays = np.array(corner_rays(fovy))  # (4, 3)
        self.cam_xpos, self.cam_xmat, self.clock = cam_xpos[:, cam], cam_xmat[:, cam], clock
        self.geo = geo
        self.period = 1.0 / config.camera_rate
        self.cos_max_tilt = math.cos(math.radians(config.max_frame_tilt_deg))
        self.nominal_half = config.altitude * math.tan(math.radians(fovy) / 2) + 1e-6
        centers = geo.centers()
        self.cx, self.cy = centers[:, 0], centers[:, 1]
        self.rows, self.cols = np.divmod(np.arange(geo.height * geo.width), geo.width)
        self.target = np.asarray(target, dtype=bool).reshape(-1)
        self.coverage = coverage
        self.min_down = min_down
        self.next_frame = np.zeros(len(clock))

    def reset(self, i: int) -> None:
        self.next_frame[i] = 0.0

    def capture(self, drones: np.ndarray) -> np.ndarray:
        """A frame of each of ``drones`` now; how many target cells each saw first."""
        pose = np.concatenate((self.cam_xpos[drones], self.cam_xmat[drones]), axis=1)
        self.next_frame[drones] = self.clock[drones] + self.period
        seen = self.seen(pose)
        rows = self.coverage[drones]
        newly = mark_seen(rows, seen, self.target)
        self.coverage[drones] = rows
        return newly

    def seen(self, pose: np.ndarray) -> np.ndarray:
        """(n, H·W) cells seen from camera poses (n, 12): world position, row-major matrix."""
        px, py, pz = pose[:, 0:1], pose[:, 1:2], pose[:, 2:3]
        m = [pose[:, 3 + k : 4 + k] for k in range(9)]
        rx, ry, rz = self.rays[:, 0], self.rays[:, 1], self.rays[:, 2]  # (4,) each
        down = -(m[6] * rx + m[7] * ry + m[8] * rz)  # (n, 4)
        level = m[8][:, 0] >= self.cos_max_tilt  # frames tilted off nadir are not used
        usable = (pz[:, 0] > 0.0) & (down >= self.min_down).all(1) & level
        with np.errstate(divide="ignore", invalid="ignore"):
            t = pz / down
            xs = px + t * (m[0] * rx + m[1] * ry + m[2] * rz)  # (n, 4) corners
            ys = py + t * (m[3] * rx + m[4] * ry + m[5] * rz)
        g = self.geo
        inv, h2, w2 = 1.0 / g.cell_size, g.height / 2, g.width / 2
        with np.errstate(invalid="ignore"):
            c_lo = np.ceil(xs.min(1) * inv + w2 - 0.5)[:, None]
            c_hi = np.floor(xs.max(1) * inv + w2 - 0.5)[:, None]
            r_lo = np.ceil(h2 - ys.max(1) * inv - 0.5)[:, None]
            r_hi = np.floor(h2 - ys.min(1) * inv - 0.5)[:, None]
        cand = (self.cols >= c_lo) & (self.cols <= c_hi) & (self.rows >= r_lo) & (self.rows <= r_hi)
        x, y = self.cx, self.cy
        pos = np.zeros(cand.shape, dtype=bool)
        neg = np.zeros(cand.shape, dtype=bool)
        for k in range(4):  # edges (corner k−1 → corner k), as inside_polygon walks them
            end = k if k else None  # k = 0: the last corner
            ax, ay = xs[:, k - 1 : end], ys[:, k - 1 : end]
            bx, by = xs[:, k : k + 1], ys[:, k : k + 1]
            cross = (bx - ax) * (y - ay) - (by - ay) * (x - ax)
            pos |= cross > 0.0
            neg |= cross < 0.0
        half = self.nominal_half
        near = (np.abs(x - px) <= half) & (np.abs(y - py) <= half)
        return cand & ~(pos & neg) & near & usable[:, None]
