"""The camera's line of sight on a map with obstacles: MuJoCo's own ray casting.

A cell in view (:func:`~cpp_mujoco.physics.sensing.kernels.frame_near`) counts as seen only if
the ray from the camera to the cell's centre on the ground reaches it before any obstacle box:
one ``mujoco.mj_multiRay`` per drone and frame, over the cells that drone has not seen yet and
whose rays may pass over a box (the kernel writes the rays; ``mark_visible`` reads the hits). The
rays are cast in an ``MjData`` of the arena's own, where only the static boxes count: the ray
test enables the obstacles' geom group alone (not the ground, not any drone) and excludes the
quadrotor's body as well.
"""

from __future__ import annotations

import mujoco
import numpy as np

from cpp_mujoco.physics.obstacles import OBSTACLE_GROUP

# a ray meets a box "first" when it does so before this fraction of the way to the cell centre:
# the centre lies on the ground, never inside a box but an obstacle cell's own
BEFORE = 1.0 - 1e-9


class RayOcclusion:
    """The ray test of ``n`` drones' frames against the obstacle boxes of ``model`` (an arena
    with them), at most ``max_rays`` rays a frame. ``body``: the quadrotor's body, left out of
    every ray. :attr:`geom` and :attr:`dist` (n, max_rays) hold each frame's hits."""

    def __init__(self, model: mujoco.MjModel, body: int, n: int, max_rays: int):
        self.model, self.data = model, mujoco.MjData(model)
        mujoco.mj_forward(model, self.data)  # the boxes are world geoms: placed once
        self.group = np.zeros(mujoco.mjNGROUP, dtype=np.uint8)
        self.group[OBSTACLE_GROUP] = 1
        self.body = int(body)
        self.geom = np.zeros((n, max_rays), dtype=np.int32)
        self.dist = np.zeros((n, max_rays))
        self.rays_cast = 0  # rays cast so far (a measure of what occlusion costs)

    def cast(self, j: int, camera: np.ndarray, rays: np.ndarray, k: int) -> None:
        """Cast ``rays[:k]`` ((k, 3), each from ``camera`` to a cell centre, so a distance of 1
        is the centre) into row ``j`` of :attr:`geom` and :attr:`dist`."""
        mujoco.mj_multiRay(
            self.model, self.data, camera, rays[:k].reshape(-1), self.group, True, self.body,
            self.geom[j, :k], self.dist[j, :k], None, k, mujoco.mjMAXVAL,
        )  # fmt: skip
        self.rays_cast += k
