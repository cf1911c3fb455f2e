"""The coverage camera's frame as one numba kernel over the drones whose frame is due.

Why compiled: a frame tests the cells of a small window under the camera (a few dozen) against
the footprint's four edges; as numpy that is ~40 calls over short arrays per frame, which at one
or a few drones costs more than the physics between frames. The rule
(:class:`~cpp_mujoco.physics.sensing.camera.CoverageCamera`): the corner rays cast to the ground,
the frame used only when level and every ray points down, a cell seen when its centre lies in the
footprint's bounding box, within the nominal footprint's half width of the camera and on no
edge's outer side. On a map with obstacles :func:`frame_near` applies the same rule and hands
the cells whose rays may meet an obstacle to the ray test
(:class:`~cpp_mujoco.physics.sensing.occlusion.RayOcclusion`). Run uncompiled
(``frame.py_func``) it is its own readable reference. Constants come in arguments (numba caches
a module's globals frozen).
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
def _view(d, cam_xpos, cam_xmat, rays, c, x_of_col, y_of_row, xs, ys, cells):
    """The cells (flat indices, row-major) drone ``d``'s frame sees now into ``cells``; how
    many. Arguments as :func:`frame`'s; ``xs``, ``ys``: room for the four ground corners."""
    cos_max_tilt, min_down, half, inv = c[0], c[1], c[2], c[3]
    height, width, kr, kc = c[4], c[5], int(c[6]), int(c[7])
    h2, w2, eps = height / 2, width / 2, 1e-6
    px, py, pz = cam_xpos[d, 0], cam_xpos[d, 1], cam_xpos[d, 2]
    m = cam_xmat[d]
    # frames tilted off nadir are not used
    usable = pz > 0.0 and m[8] >= cos_max_tilt
    usable = usable and corners(px, py, pz, m, rays, min_down, xs, ys)
    if not usable or not math.isfinite(xs.sum() + ys.sum()):
        return 0  # a NaN corner sees nothing (no comparison with it holds)
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
    count = 0
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
            cells[count] = ri * int(width) + ci
            count += 1
    return count


@njit(cache=True)
def frame(drones, cam_xpos, cam_xmat, rays, c, x_of_col, y_of_row, target, coverage, newly):
    """Mark what each of ``drones`` sees now in its ``coverage`` row; ``newly[j]`` = how many
    target cells drone ``drones[j]`` saw first. ``cam_xpos`` (n, 3) and ``cam_xmat`` (n, 9) are
    the camera poses; ``rays`` (4, 3) the corner rays in the camera frame; ``c``: cos of the
    largest frame tilt, the least downward ray component, the nominal half width (m), 1 / cell
    size, grid height, grid width, window rows, window columns."""
    xs, ys = np.empty(4), np.empty(4)
    cells = np.empty(int(c[6]) * int(c[7]), dtype=np.int64)
    for j in range(drones.size):
        d = drones[j]
        newly[j] = 0
        for k in range(_view(d, cam_xpos, cam_xmat, rays, c, x_of_col, y_of_row, xs, ys, cells)):
            cell = cells[k]
            if not coverage[d, cell]:
                coverage[d, cell] = True
                if target[cell]:
                    newly[j] += 1


@njit(cache=True)
def frame_near(drones, cam_xpos, cam_xmat, rays, c, x_of_col, y_of_row, target, coverage,
               newly, box_lo, box_hi, cells, counts, rays_to):  # fmt: skip
    """:func:`frame` on a map with obstacle boxes (corners ``box_lo``, ``box_hi``, (K, 3)): a
    drone none of whose rays to the unseen cells in view can pass over a box (the rectangle
    spanned by the camera and those cells' centres meets no box) marks them here; another marks
    nothing and leaves them in ``cells[j, :counts[j]]``, with the rays from its camera to their
    centres on the ground in ``rays_to[j]``, for the ray test (then :func:`mark_visible`)."""
    xs, ys = np.empty(4), np.empty(4)
    width = int(c[5])
    for j in range(drones.size):
        d = drones[j]
        newly[j] = 0
        row = cells[j]
        count = 0
        x_lo = x_hi = cam_xpos[d, 0]
        y_lo = y_hi = cam_xpos[d, 1]
        for k in range(_view(d, cam_xpos, cam_xmat, rays, c, x_of_col, y_of_row, xs, ys, row)):
            cell = row[k]
            if coverage[d, cell]:
                continue
            row[count] = cell
            count += 1
            x, y = x_of_col[cell % width], y_of_row[cell // width]
            x_lo, x_hi, y_lo, y_hi = min(x_lo, x), max(x_hi, x), min(y_lo, y), max(y_hi, y)
        near = False
        for b in range(box_lo.shape[0]):
            if box_lo[b, 0] <= x_hi and box_hi[b, 0] >= x_lo:
                if box_lo[b, 1] <= y_hi and box_hi[b, 1] >= y_lo:
                    near = True
        counts[j] = count if near else 0
        if near:
            for k in range(count):
                cell = row[k]
                rays_to[j, k, 0] = x_of_col[cell % width] - cam_xpos[d, 0]
                rays_to[j, k, 1] = y_of_row[cell // width] - cam_xpos[d, 1]
                rays_to[j, k, 2] = -cam_xpos[d, 2]
            continue
        for k in range(count):
            cell = row[k]
            coverage[d, cell] = True
            if target[cell]:
                newly[j] += 1


@njit(cache=True)
def mark_visible(drones, counts, cells, geom, dist, before, target, coverage, newly):
    """Mark the cells :func:`frame_near` left for the ray test whose ray met no obstacle:
    ``geom[j, k]`` < 0, or ``dist[j, k]`` (in units of the ray, 1 at the cell centre) not
    ``before`` the centre; ``newly[j]`` counts the target cells among them."""
    for j in range(drones.size):
        d = drones[j]
        for k in range(counts[j]):
            if geom[j, k] >= 0 and dist[j, k] < before:
                continue
            cell = cells[j, k]
            coverage[d, cell] = True
            if target[cell]:
                newly[j] += 1
