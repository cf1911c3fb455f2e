"""The review cameras' view of a mission: what is drawn into the scene, and where the chase
camera looks from.

:class:`MissionDecor` is the decorator a review camera calls after MuJoCo's ``update_scene``:
the map's tiles with the live coverage (seen cells lighter), the landing kerbs and no-fly
volumes (:class:`~cpp_mujoco.physics.view.scenery.Scenery`), the trail flown so far
(:class:`~cpp_mujoco.physics.view.trail.Trail`) and the enlarged airframe
(:class:`~cpp_mujoco.physics.view.airframe.Airframe`). All of it is render-time only: the
physics model and the flight never see it.

:class:`ChaseRig` moves the chase camera: the look-at point leads the UAV along its direction of
flight, and the azimuth turns to look along it, both exponentially smoothed in *simulated* time
(so a video at 10 frames/s and ``env.render()`` once per action frame the same way) and the turn
rate-limited (a reversal swings the view round over seconds, not in one frame). At the end of a
mission video the rig pulls back to the whole map, north up (:meth:`ChaseCamera.render_overview`):
the route and the coverage it earned, in one frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from cpp_mujoco.physics.view.airframe import Airframe
from cpp_mujoco.physics.view.rendering import OffscreenCamera
from cpp_mujoco.physics.view.scenery import Scenery
from cpp_mujoco.physics.view.trail import Trail

__all__ = ["ChaseCamera", "ChaseRig", "MissionDecor", "chase_camera", "onboard_camera"]

BODY = "quadrotor/core"
MODEL_VISUAL_GROUP = 2  # the quadrotor's own geoms: hidden where the airframe is drawn instead
Coverage = np.ndarray | Callable[[], np.ndarray]


class MissionDecor:
    """What a review camera adds to MuJoCo's scene, in drawing order: the map with the cells
    seen so far lighter, the trail, the airframe. ``coverage`` is the env's coverage array (read
    live: the flight marks it in place, e.g. ``env.mdp.coverage``) or a callable returning it;
    None draws nothing as seen. ``trail`` and ``airframe`` are optional."""

    def __init__(
        self,
        model: mujoco.MjModel,
        scenery: Scenery | None,
        coverage: Coverage | None = None,
        trail: Trail | None = None,
        airframe: Airframe | None = None,
    ):
        self.scenery, self.coverage, self.trail, self.airframe = scenery, coverage, trail, airframe
        self.body_id = int(model.body(BODY).id) if trail is not None else -1

    @property
    def geom_count(self) -> int:
        """Room the scene needs for one frame's decorations."""
        parts = (self.scenery, self.trail, self.airframe)
        return sum(int(p.geom_count) for p in parts if p is not None)

    def seen(self) -> np.ndarray | None:
        """The cells seen so far, flat (None: no coverage given)."""
        cov = self.coverage() if callable(self.coverage) else self.coverage
        return None if cov is None else np.asarray(cov, dtype=bool).reshape(-1)

    def __call__(self, scene: mujoco.MjvScene, data: mujoco.MjData) -> None:
        if self.scenery is not None:
            self.scenery.decorate(scene, self.seen())
        if self.trail is not None:
            self.trail.update(data.xpos[self.body_id], float(data.time))
            self.trail.decorate(scene)
        if self.airframe is not None:
            self.airframe.decorate(scene, data)


def _wrap(deg: float) -> float:
    """An angle difference in (-180, 180]."""
    return (deg + 180.0) % 360.0 - 180.0


class ChaseRig:
    """The chase camera's pose from the UAV's positions over (simulated) time.

    Look-at: the UAV plus ``lead`` seconds of its smoothed velocity (at most ``max_lead`` m),
    so the next cells are in view; smoothed with time constant ``tau_lookat``. Azimuth: along the
    smoothed horizontal velocity once it exceeds ``min_speed``, smoothed with ``tau_heading`` and
    at most ``max_turn`` deg/s; ``azimuth`` is the start (90: looking north). A time earlier than
    the last update (a reset) snaps back to the start pose. ``pull`` (0..1) blends the pose
    towards ``overview`` (look-at, distance, elevation, azimuth), eased.
    """

    def __init__(
        self,
        distance: float = 16.0,
        elevation: float = -45.0,
        azimuth: float = 90.0,
        lead: float = 1.0,
        max_lead: float = 4.0,
        tau_lookat: float = 0.5,
        tau_heading: float = 1.0,
        min_speed: float = 0.4,
        max_turn: float = 90.0,
    ):
        self.distance, self.elevation, self.start_azimuth = distance, elevation, azimuth
        self.lead, self.max_lead = lead, max_lead
        self.min_speed, self.max_turn = min_speed, max_turn
        self.tau_lookat, self.tau_heading = tau_lookat, tau_heading
        self.reset()

    def reset(self) -> None:
        self.time: float | None = None
        self.azimuth = self.start_azimuth
        self.lookat = np.zeros(3)
        self.velocity = np.zeros(3)
        self._last = np.zeros(3)
        self.pull = 0.0
        self.overview: tuple[np.ndarray, float, float, float] = (np.zeros(3), 80.0, -65.0, 90.0)

    def update(self, position, time: float) -> None:
        """Advance to the UAV's ``position`` at simulated ``time``."""
        p = np.array(position, dtype=float)
        if self.time is None or time < self.time:
            self.reset()
            self.time, self.lookat, self._last = time, p.copy(), p
            return
        dt = time - self.time
        if dt <= 0:
            return
        raw = (p - self._last) / dt
        self.time, self._last = time, p
        self.velocity += (1 - math.exp(-dt / self.tau_heading)) * (raw - self.velocity)
        ahead = self.lead * self.velocity
        ahead[2] = 0.0
        norm = float(np.linalg.norm(ahead))
        if norm > self.max_lead:
            ahead *= self.max_lead / norm
        self.lookat += (1 - math.exp(-dt / self.tau_lookat)) * (p + ahead - self.lookat)
        vx, vy = float(self.velocity[0]), float(self.velocity[1])
        if math.hypot(vx, vy) > self.min_speed:
            turn = _wrap(math.degrees(math.atan2(vy, vx)) - self.azimuth)
            turn *= 1 - math.exp(-dt / self.tau_heading)
            limit = self.max_turn * dt
            self.azimuth = (self.azimuth + max(-limit, min(limit, turn))) % 360.0

    def pose(self) -> tuple[np.ndarray, float, float, float]:
        """(look-at, distance, elevation, azimuth) of the camera now."""
        s = self.pull * self.pull * (3 - 2 * self.pull)  # smoothstep: no jolt at either end
        if s <= 0:
            return self.lookat, self.distance, self.elevation, self.azimuth
        centre, distance, elevation, azimuth = self.overview
        return (
            self.lookat + s * (centre - self.lookat),
            self.distance + s * (distance - self.distance),
            self.elevation + s * (elevation - self.elevation),
            (self.azimuth + s * _wrap(azimuth - self.azimuth)) % 360.0,
        )

    def apply(self, camera: mujoco.MjvCamera) -> None:
        lookat, camera.distance, camera.elevation, camera.azimuth = self.pose()
        camera.lookat[:] = lookat

    @property
    def heading(self) -> float:
        """World direction (deg, counter-clockwise from east) that points up in the frame."""
        return self.pose()[3]


class ChaseCamera(OffscreenCamera):
    """A free camera moved by a :class:`ChaseRig` following body ``quadrotor/core``; the
    model's own small airframe is hidden when the decor draws the enlarged one."""

    def __init__(self, model: mujoco.MjModel, rig: ChaseRig | None = None, **kwargs: Any):
        super().__init__(model, **kwargs)
        self.rig = rig or ChaseRig()
        self.body_id = int(model.body(BODY).id)
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.camera = cam
        if getattr(self.decorate, "airframe", None) is not None:
            self.scene_option.geomgroup[MODEL_VISUAL_GROUP] = 0
        scenery = getattr(self.decorate, "scenery", None)
        if scenery is not None:  # the whole map in view, north up, from a steep angle
            half = max(scenery.geometry.half_extent)
            fovy = math.radians(float(model.vis.global_.fovy))
            self.overview_pose = (np.zeros(3), 1.15 * half / math.tan(fovy / 2), -65.0, 90.0)
        else:
            self.overview_pose = self.rig.overview

    def render(self, data: mujoco.MjData) -> np.ndarray:
        self.rig.update(data.xpos[self.body_id], float(data.time))
        self.rig.apply(self.camera)
        return super().render(data)

    def render_overview(self, data: mujoco.MjData, pull: float) -> np.ndarray:
        """A frame ``pull`` (0..1) of the way from the chase view to the whole map, the state
        held (the end of a mission video; the next :meth:`render` of a new episode resets)."""
        self.rig.overview, self.rig.pull = self.overview_pose, min(max(pull, 0.0), 1.0)
        self.rig.apply(self.camera)
        return super().render(data)


def chase_camera(
    model: mujoco.MjModel,
    width: int = 512,
    height: int = 384,
    scenery: Scenery | None = None,
    coverage: Coverage | None = None,
    trail: bool = True,
    airframe: bool = True,
    rig: ChaseRig | None = None,
) -> ChaseCamera:
    """The mission's chase camera: map (``scenery``; None: the one stored in an arena model),
    ``coverage`` lighter, the trail and the enlarged airframe, a :class:`ChaseRig`'s view."""
    if scenery is None:
        scenery = Scenery.from_model(model)
    decor = MissionDecor(
        model, scenery, coverage, Trail() if trail else None, Airframe(model) if airframe else None
    )
    return ChaseCamera(model, rig=rig, width=width, height=height, decorate=decor)


def onboard_camera(
    model: mujoco.MjModel,
    width: int = 320,
    height: int = 240,
    scenery: Scenery | None = None,
    coverage: Coverage | None = None,
) -> OffscreenCamera:
    """The downward camera with the map and ``coverage`` (no trail, no airframe: the camera
    hangs under the body and looks away from both)."""
    if scenery is None:
        scenery = Scenery.from_model(model)
    decor = MissionDecor(model, scenery, coverage)
    return OffscreenCamera(
        model, camera="quadrotor/downward", width=width, height=height, decorate=decor
    )
