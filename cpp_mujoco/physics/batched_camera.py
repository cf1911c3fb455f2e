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
from cpp_mujoco.physics.batched_control import _row_max, _row_min
from cpp_mujoco.physics.camera import corner_rays
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry

_PREV = [3, 0, 1, 2]  # each footprint corner's predecessor


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
        # the window: centres within ±half of a point span at most 2·half/cell + 1 rows or
        # columns; one more (and the eps) absorbs the rounding of where the block starts
        span = math.floor(2 * self.nominal_half / geo.cell_size + 2e-6) + 2
        self._kr, self._kc = min(span, geo.height), min(span, geo.width)
        self._dr, self._dc = np.arange(float(self._kr)), np.arange(float(self._kc))
        # a centre's x depends on its column only, y on its row: the same doubles as centers()
        self._x_of_col = self.cx[: geo.width].copy()
        self._y_of_row = self.cy[:: geo.width].copy()

    def reset(self, i: int) -> None:
        self.next_frame[i] = 0.0

    def capture(self, drones: np.ndarray) -> np.ndarray:
        """A frame of each of ``drones`` now; how many target cells each saw first."""
        self.next_frame[drones] = self.clock[drones] + self.period
        cells, seen = self.seen(self.cam_xpos[drones], self.cam_xmat[drones])
        if not self.coverage.flags.c_contiguous:  # marked through a copy, as mark_seen does
            rows = self.coverage[drones]
            full = np.zeros(rows.shape, dtype=bool)
            np.put_along_axis(full, cells, seen, 1)
            newly = mark_seen(rows, full, self.target)
            self.coverage[drones] = rows
            return newly
        flat = self.coverage.reshape(-1)  # a view: marked in place
        index = cells + (drones * self.coverage.shape[1])[:, None]
        new = seen & ~flat[index]  # seen and not yet covered (no cell twice in a window)
        new &= self.target[cells]
        flat[index[seen]] = True
        return np.count_nonzero(new, axis=1)

    def seen(self, xpos: np.ndarray, xmat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cells seen from camera poses (n, 3) world positions, (n, 9) row-major matrices:
        ``(cells, seen)``, (n, K) flat cell indices (each drone's window) and whether each is
        seen. A cell is only seen inside the nominal footprint box around the camera, so only
        the fixed K-cell window of rows and columns that box can reach is tested (not the whole
        map): the tests per cell are unchanged."""
        px, py, pz = xpos[:, 0:1], xpos[:, 1:2], xpos[:, 2:3]
        m = [xmat[:, k : k + 1] for k in range(9)]
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
            c_lo = np.ceil(_row_min(xs) * inv + w2 - 0.5)[:, None]
            c_hi = np.floor(_row_max(xs) * inv + w2 - 0.5)[:, None]
            r_lo = np.ceil(h2 - _row_max(ys) * inv - 0.5)[:, None]
            r_hi = np.floor(h2 - _row_min(ys) * inv - 0.5)[:, None]
        # the window's columns and rows: the box tests are per column and per row
        r0, c0 = self._window(px[:, 0], py[:, 0])
        col = c0[:, None] + self._dc  # (n, Kc), whole numbers as floats
        row = r0[:, None] + self._dr  # (n, Kr)
        ci, ri = col.astype(np.int64), row.astype(np.int64)
        x, y = self._x_of_col[ci], self._y_of_row[ri]  # the centres' coordinates
        half = self.nominal_half
        with np.errstate(invalid="ignore"):
            ok_c = (col >= c_lo) & (col <= c_hi) & (np.abs(x - px) <= half)
            ok_r = (row >= r_lo) & (row <= r_hi) & (np.abs(y - py) <= half)
        # the four edges (corner k−1 → corner k) at once, as inside_polygon walks them:
        # (bx − ax)·(y − ay) varies by row, (by − ay)·(x − ax) by column
        ax, ay = xs[:, _PREV], ys[:, _PREV]  # (n, 4)
        by_row = ((xs - ax)[:, :, None] * (y[:, None, :] - ay[:, :, None]))[:, :, :, None]
        by_col = ((ys - ay)[:, :, None] * (x[:, None, :] - ax[:, :, None]))[:, :, None, :]
        cross = by_row - by_col  # (n, 4, Kr, Kc)
        with np.errstate(invalid="ignore"):
            mixed = (cross > 0.0).any(1) & (cross < 0.0).any(1)
        seen = ok_r[:, :, None] & ok_c[:, None, :] & ~mixed & usable[:, None, None]
        cells = (ri[:, :, None] * g.width + ci[:, None, :]).reshape(len(ci), -1)
        return cells, seen.reshape(len(ci), -1)

    def _window(self, px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(first row, first column) of each drone's window, as floats: the Kr × Kc block of
        the rows and columns whose centres can lie within ``nominal_half`` of (px, py), shifted
        to lie inside the map (the cells it then adds are tested like any other); a non-finite
        position gets any block (its frame sees nothing)."""
        g, half, eps = self.geo, self.nominal_half, 1e-6
        inv = 1.0 / g.cell_size
        with np.errstate(invalid="ignore"):
            c0 = np.floor((px - half) * inv + (g.width / 2 - 0.5 - eps))
            r0 = np.floor((g.height / 2 - 0.5 - eps) - (py + half) * inv)
        c0 = np.fmin(np.fmax(c0, 0.0), g.width - self._kc)
        r0 = np.fmin(np.fmax(r0, 0.0), g.height - self._kr)
        return r0, c0
