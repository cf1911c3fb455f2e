"""The coverage camera's frame as one numba kernel over the drones whose frame is due.

Why compiled: a frame tests the cells of a small window under the camera (a few dozen) against
the footprint's four edges; as numpy that is ~40 calls over short arrays per frame, which at one
or a few drones costs more than the physics between frames. The rule
(:class:`~cpp_mujoco.physics.sensing.camera.CoverageCamera`): the corner rays cast to the ground,
the frame used only when level and every ray points down, a cell seen when its centre lies in the
footprint's bounding box, within the nominal footprint's half width of the camera and on no
edge's outer side. Run uncompiled (``frame.py_func``) it is its own
readable reference. Constants come in arguments (numba caches a module's globals frozen).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def corners(px, py, pz, m, rays, min_down, xs, ys):
    """The image's ground corners (z = 0) into ``xs``, ``ys`` for a camera at (px, py, pz) with
    camera→world rotation ``m`` (row-major 9); False as soon as a corner ray points less than
    ``min_down`` downwards (the horizon is in view: the frame maps nothing)."""
    for k in range(4):
        rx, ry, rz = rays[k, 0], rays[k, 1], rays[k, 2]
        down = -(m[6] * rx + m[7] * ry + m[8] * rz)
        if not down >= min_down:
            return False
        t = pz / down
        xs[k] = px + t * (m[0] * rx + m[1] * ry + m[2] * rz)
        ys[k] = py + t * (m[3] * rx + m[4] * ry + m[5] * rz)
    return True


@njit(cache=True)
def frame(drones, cam_xpos, cam_xmat, rays, c, x_of_col, y_of_row, target, coverage, newly):
    """Mark what each of ``drones`` sees now in its ``coverage`` row; ``newly[j]`` = how many
    target cells drone ``drones[j]`` saw first. ``cam_xpos`` (n, 3) and ``cam_xmat`` (n, 9) are
    the camera poses; ``rays`` (4, 3) the corner rays in the camera frame; ``c``: cos of the
    largest frame tilt, the least downward ray component, the nominal half width (m), 1 / cell
    size, grid height, grid width, window rows, window columns."""
    cos_max_tilt, min_down, half, inv = c[0], c[1], c[2], c[3]
    height, width, kr, kc = c[4], c[5], int(c[6]), int(c[7])
    h2, w2, eps = height / 2, width / 2, 1e-6
    xs, ys = np.empty(4), np.empty(4)
    for j in range(drones.size):
        d = drones[j]
        newly[j] = 0
        px, py, pz = cam_xpos[d, 0], cam_xpos[d, 1], cam_xpos[d, 2]
        m = cam_xmat[d]
        # frames tilted off nadir are not used
        usable = pz > 0.0 and m[8] >= cos_max_tilt
        usable = usable and corners(px, py, pz, m, rays, min_down, xs, ys)
        if not usable or not math.isfinite(xs.sum() + ys.sum()):
            continue  # a NaN corner sees nothing (no comparison with it holds)
        x_lo, x_hi, y_lo, y_hi = xs.min(), xs.max(), ys.min(), ys.max()
        c_lo = math.ceil(x_lo * inv + w2 - 0.5)
        c_hi = math.floor(x_hi * inv + w2 - 0.5)
        r_lo = math.ceil(h2 - y_hi * inv - 0.5)
        r_hi = math.floor(h2 - y_lo * inv - 0.5)
        # the window: the kr × kc block of rows and columns whose centres can lie within
        # ``half`` of the camera, shifted to lie inside the map
        c0 = math.floor((px - half) * inv + (width / 2 - 0.5 - eps))
        r0 = math.floor((height / 2 - 0.5 - eps) - (py + half) * inv)
        c0 = min(max(c0, 0.0), width - kc)
        r0 = min(max(r0, 0.0), height - kr)
        for a in range(kr):
            row = r0 + a
            ri = int(row)
            y = y_of_row[ri]
            if not (row >= r_lo and row <= r_hi and abs(y - py) <= half):
                continue
            for b in range(kc):
                col = c0 + b
                ci = int(col)
                x = x_of_col[ci]
                if not (col >= c_lo and col <= c_hi and abs(x - px) <= half):
                    continue
                positive = negative = False
                for k in range(4):  # edge corner k−1 → corner k: inside on one side of every edge
                    p = (k + 3) % 4
                    cross = (xs[k] - xs[p]) * (y - ys[p]) - (ys[k] - ys[p]) * (x - xs[p])
                    positive |= cross > 0.0
                    negative |= cross < 0.0
                if positive and negative:
                    continue
                cell = ri * int(width) + ci
                if not coverage[d, cell]:
                    coverage[d, cell] = True
                    if target[cell]:
                        newly[j] += 1
