"""Speed of the review tools: onboard and chase rendering, and what a Rerun recording adds to a
mission."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import gymnasium as gym

from cpp_mujoco.missions.mission import fly_mission
from cpp_mujoco.physics.view.rendering import OffscreenCamera, configure_gl
from cpp_mujoco.planners import SafeGreedyPlanner
from cpp_mujoco.review.flight_review import hud_state
from cpp_mujoco.review.hud import Hud


def benchmark_review(map_name: str = "B", budget: int = 40, frames: int = 200) -> dict:
    """Onboard camera frames/s at 320×240, chase camera frames/s at 512×384 as a mission video
    draws it (map, coverage, a full trail, the airframe, the HUD), and mission wall time with and
    without a recording.

    The mission is flown by the safe greedy planner in MuJoCo, writing the onboard video in both
    runs, so the difference is the recording alone (pose, footprint, compressed frames, metrics).
    """
    import mujoco  # GL: MuJoCo and dm_control only after run() chose the backend

    from cpp_mujoco.physics.view.scenery import Scenery  # GL: as above

    env = gym.make("cpp_mujoco/MuJoCo-v0", map=map_name).unwrapped
    env.reset(seed=0)
    scenery = Scenery(env.grid_map, env.config)  # as a mission's onboard camera draws the map
    camera = OffscreenCamera(
        env.model, camera="quadrotor/downward", width=320, height=240, decorate=scenery
    )
    camera.render(env.data)
    start = time.perf_counter()
    for i in range(frames):
        env.data.qpos[0] = 0.01 * i  # a moving scene, not one cached frame
        mujoco.mj_forward(env.model, env.data)
        camera.render(env.data)
    fps = frames / (time.perf_counter() - start)
    camera.close()
    chase_fps = _chase_fps(env, scenery, frames)

    with tempfile.TemporaryDirectory() as tmp:
        video = Path(tmp) / "onboard.mp4"
        plain = fly_mission(SafeGreedyPlanner(), map_name, budget=budget, onboard_video=video)
        recorded = fly_mission(
            SafeGreedyPlanner(),
            map_name,
            budget=budget,
            onboard_video=video,
            rrd=Path(tmp) / "m.rrd",
        )
        size_mb = (Path(tmp) / "m.rrd").stat().st_size / 1e6
    return {
        "onboard_render_320x240_fps": fps,
        "chase_render_512x384_fps": chase_fps,
        "mission_with_video_s": plain.wall_time_s,
        "mission_with_video_and_rrd_s": recorded.wall_time_s,
        "rerun_overhead_ratio": recorded.wall_time_s / plain.wall_time_s - 1.0,
        "recording_mb": size_mb,
        "mission_actions": plain.steps,
    }


def _chase_fps(env, scenery, frames: int) -> float:
    """Chase frames/s with everything a mission video draws, the trail at its longest."""
    import mujoco  # GL: as in benchmark_review

    from cpp_mujoco.physics.view.chase import chase_camera  # GL: as in benchmark_review

    env.mdp.coverage[0, ::2] = True  # half the map seen: both tile colours in view
    camera = chase_camera(env.model, 512, 384, scenery=scenery, coverage=env.mdp.coverage)
    trail = camera.decorate.trail
    hx, hy = env.flight.geo.half_extent
    for i in range(4 * trail.max_points):  # a lawnmower over the map: the trail fills up
        trail.update((-hx + (i % 50) * 2 * hx / 50, -hy + (i // 50) * 2.0, 6.0), 0.1 * i)
    hud = Hud(512, 384)
    data, t0 = env.data, 0.1 * 4 * trail.max_points
    start = time.perf_counter()
    for i in range(frames):
        data.qpos[0] = 0.01 * i
        data.time = t0 + 0.1 * i  # the rig and the trail see time go on
        mujoco.mj_forward(env.model, data)
        state = hud_state(env, map_name=env.grid_map.label, policy="-", budget=50, action=1,
                          view_up=camera.rig.heading)  # fmt: skip
        hud.draw(camera.render(data), state)
    fps = frames / (time.perf_counter() - start)
    camera.close()
    env.mdp.coverage[:] = False
    return fps


def run() -> dict:
    """The ``review`` section as ``cpp-mujoco benchmark`` runs it (the GL backend chosen first)."""
    configure_gl()
    return benchmark_review()
