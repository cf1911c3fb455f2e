"""The path flown so far, drawn into a rendered scene as a polyline.

Why a trail: a video frame shows where the UAV is, not how it got there; the trail makes the
policy's route (and a detour the wind forced) readable in any single frame, including a still.
The points are the tracked body's positions as frames are rendered, one kept every ``spacing``
metres; the count is capped (``max_points``): when full, every other point is dropped, so the
whole route stays drawn at a coarser step and a frame never costs more than ``max_points`` geoms.
A rendered time earlier than the last one (a reset) starts a new trail. The segments are GL lines
of a fixed width in pixels: unlit and a few vertices each, so 200 of them cost the software
renderer next to nothing (capsules cost ~10 ms a 512×384 frame), and the trail reads as well far
from the camera as near it.
"""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["TRAIL_RGBA", "Trail"]

TRAIL_RGBA = (0.85, 0.15, 0.85, 1.0)  # magenta: no zone of the map has it
TRAIL_WIDTH = 4.0  # px


class Trail:
    """Positions flown so far (kept every ``spacing`` m, at most ``max_points``) and their
    line segments. :meth:`update` takes a position; :meth:`decorate` draws the polyline through the
    kept points to the latest position."""

    def __init__(
        self,
        spacing: float = 0.5,
        max_points: int = 200,
        width: float = TRAIL_WIDTH,
        rgba: tuple[float, float, float, float] = TRAIL_RGBA,
    ):
        if max_points < 2:
            raise ValueError(f"a trail needs max_points >= 2, got {max_points}")
        self.spacing, self.max_points, self.width = spacing, max_points, width
        self.rgba = np.array(rgba, dtype=np.float32)
        self.points: list[np.ndarray] = []
        self.head: np.ndarray | None = None  # the latest position (the segment to the UAV)
        self._time = -np.inf

    @property
    def geom_count(self) -> int:
        """The most geoms one :meth:`decorate` adds."""
        return self.max_points

    def reset(self) -> None:
        self.points.clear()
        self.head = None
        self._time = -np.inf

    def update(self, position, time: float) -> None:
        """Take the body's ``position`` at simulated ``time``; an earlier time is a new episode."""
        if time < self._time:
            self.reset()
        self._time = time
        p = np.array(position, dtype=float)
        self.head = p
        if self.points and np.linalg.norm(p - self.points[-1]) < self.spacing:
            return
        self.points.append(p)
        if len(self.points) > self.max_points:
            # coarser, not shorter: keep the first point, every other one, and the newest
            self.points = [*self.points[:-1:2], self.points[-1]]

    def decorate(self, scene: mujoco.MjvScene) -> None:
        """Append the polyline's segments (as many as fit: a trail is never worth an error)."""
        if self.head is None:
            return
        path = [*self.points, self.head] if self.points[-1] is not self.head else self.points
        room = scene.maxgeom - scene.ngeom
        if room <= 0 or len(path) < 2:
            return
        path = path[-(room + 1) :]
        line = int(mujoco.mjtGeom.mjGEOM_LINE)
        init, connect, geoms = mujoco.mjv_initGeom, mujoco.mjv_connector, scene.geoms
        size, eye, rgba, width = np.zeros(3), np.eye(3).ravel(), self.rgba, self.width
        start = scene.ngeom
        n = 0
        for a, b in zip(path[:-1], path[1:], strict=True):
            if a is b or not np.any(a != b):
                continue  # a zero-length segment has no direction
            geom = geoms[start + n]
            init(geom, line, size, a, eye, rgba)
            connect(geom, line, width, a, b)
            n += 1
        scene.ngeom = start + n
