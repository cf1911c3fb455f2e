"""Fly one mission with a policy and review it: a Rerun recording, chase and onboard videos.

Works with either backend. In MuJoCo, the recorder and the cameras are fed at the camera frame
rate from inside the flight (``Flight.on_frame``); on the grid, poses are the cell centres at
cruise altitude, one per action, and the footprint is the 3×3 square.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.maps import GridMap, load_map


@dataclass
class MissionOutcome:
    """Summary of one flown mission."""

    map: str
    backend: str
    start: tuple[int, int]
    budget: int
    steps: int
    landed: bool
    crashed: bool
    crash_reason: str | None
    coverage_ratio: float
    total_reward: float
    energy_used_j: float
    flight_time_s: float
    nfz_violations: int
    wall_time_s: float
    actions: list[int] = field(default_factory=list)
    files: dict[str, str] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _batch(obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {k: np.asarray(v)[None] for k, v in obs.items()}


def fly_mission(
    policy,
    map: str | os.PathLike | GridMap,  # noqa: A002 - the env keyword
    *,
    budget: int,
    start: tuple[int, int] | None = None,
    backend: str = "mujoco",
    seed: int = 0,
    rrd: str | os.PathLike | None = None,
    video: str | os.PathLike | None = None,
    onboard_video: str | os.PathLike | None = None,
    image_every: int = 2,
    **env_kwargs: Any,
) -> MissionOutcome:
    """Fly one episode greedily with ``policy`` (anything with batched ``act``).

    ``rrd``: write a Rerun recording; ``video`` / ``onboard_video``: MP4s of the chase and the
    downward camera (MuJoCo only). ``image_every``: log every n-th camera frame to the recording.
    ``env_kwargs`` go to the env (``wind_speed=6`` …).
    """
    from cpp_mujoco.review.recording import MissionRecorder

    grid_map = load_map(map)
    if start is None:
        start = tuple(int(v) for v in np.argwhere(grid_map.landing)[0])
    env_id = {"mujoco": "cpp_mujoco/MuJoCo-v0", "grid": "cpp_mujoco/Grid-v0"}.get(backend)
    if env_id is None:
        raise ValueError(f"unknown backend {backend!r}; choose mujoco or grid")
    if backend == "grid" and (video or onboard_video):
        raise ValueError("videos need the mujoco backend")
    env = gym.make(env_id, map=grid_map, **env_kwargs).unwrapped
    obs, info = env.reset(seed=seed, options={"start": start, "budget": budget})
    physics = backend == "mujoco"
    cell_size = env.config.cell_size if physics else 4.0
    altitude = env.config.altitude if physics else 6.0
    recorder = MissionRecorder(rrd, grid_map, cell_size, altitude) if rrd else None
    cameras, writers = [], []
    wall = time.perf_counter()
    try:
        if physics:
            cameras, writers = _attach_flight_review(
                env, recorder, video, onboard_video, image_every
            )
        actions, total = [], 0.0
        sim_time = 0.0
        if recorder is not None and not physics:
            _log_grid_pose(recorder, grid_map, info["position"], cell_size, altitude, 0.0)
        terminated = False
        while not terminated:
            action = int(np.asarray(policy.act(_batch(obs)))[0])
            obs, reward, terminated, _, info = env.step(action)
            actions.append(action)
            total += reward
            sim_time = info.get("flight_time_s", len(actions) * 3.0)
            if recorder is not None:
                if not physics:
                    _log_grid_pose(
                        recorder, grid_map, info["position"], cell_size, altitude, sim_time
                    )
                cell = info["position"][0] * grid_map.shape[1] + info["position"][1]
                recorder.log_step(sim_time, action, reward, info, obs["coverage"], cell)
    finally:
        if recorder is not None:
            recorder.close()
        for writer in writers:
            writer.close()
        for camera in cameras:
            camera.close()
        if physics:
            env.flight.on_frame = None
    files = {"rrd": rrd, "video": video, "onboard_video": onboard_video}
    return MissionOutcome(
        map=grid_map.name,
        backend=backend,
        start=tuple(start),
        budget=budget,
        steps=len(actions),
        landed=info["landed"],
        crashed=info["crashed"],
        crash_reason=info.get("crash_reason"),
        coverage_ratio=info["coverage_ratio"],
        total_reward=total,
        energy_used_j=info.get("energy_used_j", float("nan")),
        flight_time_s=info.get("flight_time_s", sim_time),
        nfz_violations=info.get("nfz_violations", 0),
        wall_time_s=time.perf_counter() - wall,
        actions=actions,
        files={k: str(v) for k, v in files.items() if v},
    )


def _log_grid_pose(recorder, grid_map, position, cell_size, altitude, time_s) -> None:
    h, w = grid_map.shape
    row, col = position
    x, y = (col + 0.5 - w / 2) * cell_size, (h / 2 - row - 0.5) * cell_size
    half = 1.5 * cell_size
    square = np.array([[x - half, y - half], [x + half, y - half], [x + half, y + half],
                       [x - half, y + half]])  # fmt: skip
    recorder.log_pose(time_s, [x, y, altitude], (1, 0, 0, 0), square)


def _attach_flight_review(env, recorder, video, onboard_video, image_every):
    """Hook the recorder and the cameras into the flight's camera frames."""
    from cpp_mujoco.review.rendering import OffscreenCamera, VideoWriter

    flight, data, model = env.flight, env.data, env.model
    fps = env.config.camera_rate
    cameras, writers = [], []
    onboard = None
    if onboard_video or recorder is not None:
        onboard = OffscreenCamera(model, camera="quadrotor/downward")
        cameras.append(onboard)
    chase = None
    if video:
        chase = OffscreenCamera(
            model,
            track_body="quadrotor/core",
            width=480,
            height=360,
            distance=16.0,
            elevation=-45.0,
        )
        cameras.append(chase)
        writers.append(VideoWriter(video, fps=fps))
    onboard_writer = None
    if onboard_video:
        onboard_writer = VideoWriter(onboard_video, fps=fps)
        writers.append(onboard_writer)
    chase_writer = writers[0] if video else None
    body = flight.params.body_id
    count = 0

    def on_frame(f) -> None:
        nonlocal count
        t = float(data.time)
        image = None
        if onboard_writer is not None or (recorder is not None and count % image_every == 0):
            image = onboard.render(data)
        if onboard_writer is not None:
            onboard_writer.write(image)
        if chase_writer is not None:
            chase_writer.write(chase.render(data))
        if recorder is not None:
            poly = f.last_footprint
            recorder.log_pose(
                t, data.xpos[body], data.xquat[body], np.asarray(poly) if poly else None
            )
            if count % image_every == 0:
                recorder.log_camera(t, image)
        count += 1

    flight.on_frame = on_frame
    return cameras, writers
