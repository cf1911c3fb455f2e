"""A mission's cameras hooked into its MuJoCo flight: chase and onboard videos with a HUD, the
recording's camera images, fed at the camera frame rate from inside the flight.

Why here and not in the env: the env renders one frame per action (``render()``), while a
review video wants every camera frame of the flight, the coverage as it grows, the action being
flown and the numbers of the moment (:class:`~cpp_mujoco.review.hud.HudState`). Everything here
only reads the simulation (``data``, the flight's energy, the coverage array); the flight is the
same with or without it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from cpp_mujoco.grid.actions import ACTION_NAMES
from cpp_mujoco.physics.view.rendering import VideoWriter
from cpp_mujoco.review.hud import Hud, HudState, view_up_heading, wind_heading

__all__ = ["ActionTap", "FlightReview", "hud_state", "outcome_status"]

HOLD_S = 2.0  # s of the final state, with the outcome, at the end of each video


class ActionTap:
    """The env as :func:`~cpp_mujoco.protocol.episode.run_episode` drives it, noting each action
    before
    it is flown: the HUD names the action of the move in the frame, which the env's own hooks
    learn only after the move."""

    def __init__(self, env: Any):
        self.env = env
        self.action: int | None = None

    def __getattr__(self, name: str) -> Any:
        return getattr(self.env, name)

    def step(self, action):
        self.action = int(action)
        return self.env.step(action)


def hud_state(
    env: Any,
    *,
    map_name: str,
    policy: str,
    budget: float,
    action: int | None,
    view_up: float,
    status: str | None = None,
) -> HudState:
    """The HUD's numbers for a ``MuJoCo-v0`` env at this instant: the budget left is the pack's
    drawable energy in units (fractional mid-move), the coverage the target cells seen."""
    f = env.flight
    target = env.grid_map.target.reshape(-1)
    seen = np.asarray(env.mdp.coverage[0], dtype=bool)
    name = None if action is None else ACTION_NAMES[action]
    if name is not None and env.guard is not None and env.guard.active:
        name += " (guard: home)"  # the return guard overrode the policy's action
    return HudState(
        map_name=map_name,
        policy=policy,
        time_s=float(env.data.time),
        budget_left=max(f.capacity[0] - f.energy_used[0], 0.0) / env.unit_energy,
        budget_start=budget,
        energy_used_j=float(f.energy_used[0]),
        state_of_charge=float(f.battery.soc[0]),
        coverage=float((seen & target).sum() / max(int(target.sum()), 1)),
        action=name,
        wind_speed=float(env.config.wind_speed),
        wind_heading=wind_heading(env.config.wind_vector),
        view_up=view_up,
        status=status,
    )


def outcome_status(info: dict[str, Any]) -> str:
    """The end of a mission in a few words, for the HUD's banner."""
    if info.get("landed"):
        return f"landed · coverage {info.get('coverage_ratio', 0.0):.0%}"
    if info.get("crashed"):
        return f"crashed: {info.get('crash_reason') or 'budget exhausted'}"
    return "mission over"


class FlightReview:
    """Opens the cameras and video writers of one mission (appended to ``cameras`` and
    ``writers`` as they open, so the caller closes whatever did); :meth:`on_frame` is the
    flight's frame hook; :meth:`finish` holds the last state with the outcome for ``HOLD_S``,
    the chase camera pulling back to the whole map over its first half.

    ``about``: ``map_name``, ``policy``, ``budget`` for the HUD; ``tap``: the
    :class:`ActionTap` the episode runs through; ``on_chase_frame``: also gets every HUD-ed
    chase frame (the docs' stills), which renders the chase camera even without a video.
    """

    def __init__(
        self,
        env: Any,
        recorder: Any,
        video: Any,
        onboard_video: Any,
        image_every: int,
        cameras: list,
        writers: list,
        *,
        about: dict[str, Any],
        tap: ActionTap | None = None,
        on_chase_frame: Callable[[np.ndarray], None] | None = None,
        hud: bool = True,
    ):
        from cpp_mujoco.physics.view.chase import chase_camera, onboard_camera  # heavy: MuJoCo
        from cpp_mujoco.physics.view.scenery import Scenery  # heavy: MuJoCo, dm_control

        self.env, self.recorder, self.image_every = env, recorder, image_every
        self.about, self.tap, self.on_chase_frame = about, tap, on_chase_frame
        self.fps = env.config.camera_rate
        scenery = Scenery(env.grid_map, env.config)  # the map's tiles: not in the physics model
        coverage = env.mdp.coverage  # marked in place by the flight's camera
        self.onboard = self.chase = None
        if onboard_video or recorder is not None:
            self.onboard = onboard_camera(env.model, scenery=scenery, coverage=coverage)
            cameras.append(self.onboard)
        if video or on_chase_frame is not None:
            self.chase = chase_camera(env.model, scenery=scenery, coverage=coverage)
            cameras.append(self.chase)
        self.chase_writer = self.onboard_writer = None
        if video:
            self.chase_writer = VideoWriter(video, fps=self.fps)
            writers.append(("video", self.chase_writer))
        if onboard_video:
            self.onboard_writer = VideoWriter(onboard_video, fps=self.fps)
            writers.append(("onboard_video", self.onboard_writer))
        self.chase_hud = Hud(self.chase.width, self.chase.height) if hud and self.chase else None
        self.onboard_hud = (
            Hud(self.onboard.width, self.onboard.height) if hud and self.onboard else None
        )
        self._cam = int(env.model.camera("quadrotor/downward").id)
        self._body = env.flight.params.body_id
        self.count = 0

    def _state(self, view_up: float, status: str | None) -> HudState:
        action = self.tap.action if self.tap is not None else None
        return hud_state(self.env, action=action, view_up=view_up, status=status, **self.about)

    def _frames(
        self, status: str | None = None, chase_too: bool = True
    ) -> tuple[np.ndarray | None, ...]:
        """(raw onboard, HUD-ed onboard, HUD-ed chase) of the current state, as needed."""
        data = self.env.data
        raw = onboard = chase = None
        if self.onboard is not None and (
            self.onboard_writer is not None
            or (self.recorder is not None and self.count % self.image_every == 0)
        ):
            raw = onboard = self.onboard.render(data)
            if self.onboard_hud is not None and self.onboard_writer is not None:
                up = view_up_heading(data.cam_xmat[self._cam])
                onboard = self.onboard_hud.draw(raw, self._state(up, status))
        if self.chase is not None and chase_too:
            chase = self.chase.render(data)
            if self.chase_hud is not None:
                chase = self.chase_hud.draw(chase, self._state(self.chase.rig.heading, status))
        return raw, onboard, chase

    def on_frame(self, env: Any) -> None:
        data, recorder = env.data, self.recorder
        raw, onboard, chase = self._frames()
        if self.onboard_writer is not None:
            self.onboard_writer.write(onboard)
        if chase is not None:
            if self.chase_writer is not None:
                self.chase_writer.write(chase)
            if self.on_chase_frame is not None:
                self.on_chase_frame(chase)
        if recorder is not None:
            t, body = float(data.time), self._body
            poly = env.footprint
            wind = env.flight.wind_now[0]  # what the last tick flew in (NaN before the first)
            recorder.log_pose(
                t, data.xpos[body], data.xquat[body], np.asarray(poly) if poly else None,
                wind=tuple(wind.tolist()) if np.isfinite(wind).all() else None,
            )  # fmt: skip
            if self.count % self.image_every == 0:
                recorder.log_camera(t, raw)
        self.count += 1

    def finish(self, status: str) -> None:
        """Hold the final state for ``HOLD_S`` in each video, the outcome in the HUD's banner;
        the chase view pulls back to the whole map (route and coverage) and stays there. The
        last chase frame goes to ``on_chase_frame`` once."""
        if self.chase_writer is None and self.onboard_writer is None and not self.on_chase_frame:
            return
        _, onboard, _ = self._frames(status, chase_too=False)  # the chase: pulled back below
        frames = max(2, round(HOLD_S * self.fps))
        pulling = frames // 2
        chase = None
        for k in range(frames):
            if self.onboard_writer is not None:
                self.onboard_writer.write(onboard)
            if self.chase is not None and (chase is None or k < pulling):
                chase = self.chase.render_overview(self.env.data, (k + 1) / pulling)
                if self.chase_hud is not None:
                    state = self._state(self.chase.rig.heading, status)
                    chase = self.chase_hud.draw(chase, state)
            if self.chase_writer is not None:
                self.chase_writer.write(chase)
        if self.on_chase_frame is not None and chase is not None:
            self.on_chase_frame(chase)
