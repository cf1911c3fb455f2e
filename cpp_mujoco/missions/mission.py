"""Fly one mission with a policy and review it: a Rerun recording, chase and onboard videos.

The episode is the protocol's own :func:`~cpp_mujoco.protocol.episode.run_episode`; the review is
added
through its hooks (the files are opened after the reset, so a bad start writes nothing). Works
with either backend. In MuJoCo, the recorder and the cameras are fed at the camera frame rate
from inside the flight (``MuJoCoEnv.on_frame``); on the grid, poses are the cell centres at cruise
altitude, one per action, and the footprint is the 3×3 square.

An interrupted mission (Ctrl-C, or SIGTERM inside :func:`cpp_mujoco.util.signals.interruptible`)
finalises its files before the interrupt goes on: the recording gets its footer and a last event
saying it was cut, each video is finalised as ``<stem>.partial.mp4``; the exception carries the
files in ``files_finalised`` (kind → path) for the message.
"""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.physics.obstacles import obstacle_boxes
from cpp_mujoco.protocol.episode import run_episode
from cpp_mujoco.protocol.policy import check_fits, policy_name
from cpp_mujoco.review.flight_review import ActionTap, FlightReview, outcome_status
from cpp_mujoco.util.signals import Terminated

# the grid backend's clock in the recording: one nominal move per action
GRID_ACTION_S = PhysicsConfig().move_duration


@dataclass
class MissionOutcome:
    """Summary of one flown mission; ``map`` is the map's unambiguous label, ``conditions`` the
    seed and env options that, with map, policy and backend, decide the numbers."""

    map: str
    policy: str
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
    conditions: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


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
    progress: bool = False,
    on_chase_frame: Callable[[np.ndarray], None] | None = None,
    any_map: bool = False,
    **env_kwargs: Any,
) -> MissionOutcome:
    """Fly one episode greedily with ``policy`` (anything with batched ``act``).

    ``rrd``: write a Rerun recording; ``video`` / ``onboard_video``: MP4s of the chase and the
    downward camera with a HUD (MuJoCo only; :mod:`cpp_mujoco.review.flight_review`).
    ``image_every``: log every n-th camera frame to the recording. ``on_chase_frame``: also gets
    every HUD-ed chase frame, the last one with the outcome (MuJoCo only).
    ``env_kwargs`` go to the env (``wind_speed=6`` …). ``progress``: a tqdm bar over actions.
    A policy that does not fit the map (an agent trained on another map) is refused
    (:class:`~cpp_mujoco.protocol.policy.MapMismatchError`) unless ``any_map``.
    """
    grid_map = load_map(map)
    check_fits(policy, grid_map, any_map)
    if start is None:
        start = tuple(int(v) for v in np.argwhere(grid_map.landing)[0])
    env_id = {"mujoco": "cpp_mujoco/MuJoCo-v0", "grid": "cpp_mujoco/Grid-v0"}.get(backend)
    if env_id is None:
        raise ValueError(f"unknown backend {backend!r}; choose mujoco or grid")
    if backend == "grid" and (video or onboard_video or on_chase_frame):
        raise ValueError("videos need the mujoco backend")
    env = gym.make(env_id, map=grid_map, **env_kwargs).unwrapped
    tap = ActionTap(env)  # the HUD names the action being flown
    physics = backend == "mujoco"
    world = env.config if physics else PhysicsConfig()  # the grid is drawn at the default scale
    cell_size, altitude = world.cell_size, world.altitude
    fov = (env.grid_config if physics else env.config).fov_side
    review: dict[str, Any] = {"recorder": None, "cameras": [], "writers": [], "flight": None}
    bar = tqdm(total=budget, desc=f"fly {grid_map.label}", unit="action", disable=not progress)
    count = itertools.count(1)

    def open_review(obs, info) -> None:
        """After the reset (a bad start opens no file): the recording, the flight's cameras."""
        if rrd:
            from cpp_mujoco.review.recording import MissionRecorder  # heavy: rerun, only for rrd

            about = {"policy": policy_name(policy), "backend": backend, "budget": budget,
                     "start": tuple(start), "seed": seed, **env_kwargs}  # fmt: skip
            review["recorder"] = MissionRecorder(
                rrd, grid_map, cell_size, altitude, properties=about, wind=physics
            )
            if grid_map.has_obstacles:
                _log_obstacles(review["recorder"], grid_map, world)
        recorder = review["recorder"]
        if physics:  # fills cameras and writers as it opens them, so all get closed
            about = {"map_name": grid_map.label, "policy": policy_name(policy), "budget": budget}
            review["flight"] = FlightReview(
                env, recorder, video, onboard_video, image_every, review["cameras"],
                review["writers"], about=about, tap=tap, on_chase_frame=on_chase_frame,
            )  # fmt: skip
            env.on_frame = review["flight"].on_frame
        elif recorder is not None:
            _log_grid_pose(recorder, grid_map, info["position"], cell_size, altitude, 0.0, fov)

    def log_step(action, obs, reward, info) -> None:
        bar.update()
        sim_time = info.get("flight_time_s", next(count) * GRID_ACTION_S)
        recorder = review["recorder"]
        if recorder is None:
            return
        if not physics:
            _log_grid_pose(recorder, grid_map, info["position"], cell_size, altitude, sim_time, fov)
        cell = info["position"][0] * grid_map.shape[1] + info["position"][1]
        recorder.log_step(sim_time, action, reward, info, obs["coverage"], cell)

    wall = time.perf_counter()
    try:
        episode = run_episode(
            tap, policy, seed=seed, options={"start": start, "budget": budget},
            on_start=open_review, on_step=log_step,
        )  # fmt: skip
        if review["flight"] is not None:
            review["flight"].finish(outcome_status(episode.info))
    except BaseException as exc:
        bar.close()
        files = _finalise(review["recorder"], review["writers"], review["cameras"], _reason(exc))
        exc.files_finalised = files  # type: ignore[attr-defined]
        raise
    finally:
        if physics:
            env.on_frame = None
    bar.close()
    files = _finalise(review["recorder"], review["writers"], review["cameras"], None)
    info = episode.info
    return MissionOutcome(
        map=grid_map.label,
        policy=policy_name(policy),
        backend=backend,
        start=tuple(start),
        budget=budget,
        steps=episode.steps,
        landed=info["landed"],
        crashed=info["crashed"],
        crash_reason=info.get("crash_reason"),
        coverage_ratio=info["coverage_ratio"],
        total_reward=episode.total_reward,
        energy_used_j=info.get("energy_used_j", float("nan")),
        flight_time_s=info.get("flight_time_s", episode.steps * GRID_ACTION_S),
        nfz_violations=info.get("nfz_violations", 0),
        wall_time_s=time.perf_counter() - wall,
        actions=episode.actions,
        files=files,
        conditions={"seed": seed, **env_kwargs},
    )


def _reason(exc: BaseException) -> str:
    if isinstance(exc, Terminated):
        return "SIGTERM"
    if isinstance(exc, KeyboardInterrupt):
        return "Ctrl-C"
    return f"{type(exc).__name__}: {str(exc)[:120]}"


def _finalise(recorder, writers, cameras, interrupted: str | None) -> dict[str, str]:
    """Close everything (each even if another fails); kind → path of each file written.
    ``interrupted``: why the mission stopped early — videos become ``.partial.mp4``."""
    files: dict[str, str] = {}
    failure: BaseException | None = None
    closers = [("rrd", lambda: recorder.close(interrupted))] if recorder is not None else []
    closers += [(kind, lambda w=w: w.close(partial=bool(interrupted))) for kind, w in writers]
    closers += [("", camera.close) for camera in cameras]
    for kind, close in closers:
        try:
            path = close()
        except Exception as exc:  # noqa: BLE001 - the first failure is raised below
            failure = failure or exc
            continue
        if kind and path is not None:
            files[kind] = str(path)
    if failure is not None and interrupted is None:
        raise failure
    return files


def _log_obstacles(recorder, grid_map: GridMap, world: PhysicsConfig) -> None:
    """The map's obstacles in the recording as the arena's boxes, at their heights and in their
    colours (a building's, a low obstacle's): the grid backend draws them at ``world``'s too."""
    import rerun as rr  # heavy: rerun, only for rrd

    boxes = obstacle_boxes(grid_map, world)
    recorder.rec.log(
        "world/obstacles",
        rr.Boxes3D(
            centers=boxes.centers,
            half_sizes=boxes.half_sizes,
            colors=np.round(boxes.rgba() * 255).astype(np.uint8),
            fill_mode="solid",
        ),
        static=True,
    )


def _log_grid_pose(recorder, grid_map, position, cell_size, altitude, time_s, fov_side) -> None:
    x, y = GridGeometry.of(grid_map, cell_size).cell_center(*position)
    half = fov_side / 2 * cell_size
    square = np.array([[x - half, y - half], [x + half, y - half], [x + half, y + half],
                       [x - half, y + half]])  # fmt: skip
    recorder.log_pose(time_s, [x, y, altitude], (1, 0, 0, 0), square)
