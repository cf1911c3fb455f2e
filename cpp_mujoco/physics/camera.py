"""Camera footprint geometry: the frustum of the downward camera intersected with the ground.

No rendering: from the camera pose (``data.cam_xpos``, ``data.cam_xmat``) the four corner rays of
the square image are intersected with the ground plane z = 0, and the cells whose centres lie in
that quadrilateral are seen. A MuJoCo camera looks along its local −z with +y up in the image, so
the corner rays of a square image with half-angle θ are (±tanθ, ±tanθ, −1).

Written in scalars: the polygon has four corners and only the ~10–20 cells under its bounding box
are tested, where numpy's per-call overhead would cost more than the arithmetic.
"""

from __future__ import annotations

import math

from cpp_mujoco.physics.arena import GridGeometry

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
    inv = 1.0 / geo.cell_size
    h2, w2 = geo.height / 2, geo.width / 2
    # centre of (r, c): x = (c + ½ − W/2)·cs  →  c ∈ [x_min/cs + W/2 − ½, x_max/cs + W/2 − ½]
    c_lo = max(0, math.ceil(min(xs) * inv + w2 - 0.5))
    c_hi = min(geo.width - 1, math.floor(max(xs) * inv + w2 - 0.5))
    r_lo = max(0, math.ceil(h2 - max(ys) * inv - 0.5))
    r_hi = min(geo.height - 1, math.floor(h2 - min(ys) * inv - 0.5))
    cs, w = geo.cell_size, geo.width
    found = []
    for r in range(r_lo, r_hi + 1):
        y = (h2 - r - 0.5) * cs
        for c in range(c_lo, c_hi + 1):
            if inside_polygon(polygon, (c + 0.5 - w2) * cs, y):
                found.append(r * w + c)
    return found
