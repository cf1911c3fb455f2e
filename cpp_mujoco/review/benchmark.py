"""Speed of the review tools: onboard rendering, and what a Rerun recording adds to a mission."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path


def benchmark_review(map_name: str = "B", budget: int = 40, frames: int = 200) -> dict:
    """Onboard camera frames/s at 320×240, and mission wall time with and without a recording.

    The mission is flown by the safe greedy planner in MuJoCo, writing the onboard video in both
    runs, so the difference is the recording alone (pose, footprint, compressed frames, metrics).
    """
    import gymnasium as gym
    import mujoco

    from cpp_mujoco.mission import fly_mission
    from cpp_mujoco.planners import SafeGreedyPlanner
    from cpp_mujoco.review.rendering import OffscreenCamera
    from cpp_mujoco.review.scenery import Scenery

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
        "mission_with_video_s": plain.wall_time_s,
        "mission_with_video_and_rrd_s": recorded.wall_time_s,
        "rerun_overhead_ratio": recorded.wall_time_s / plain.wall_time_s - 1.0,
        "recording_mb": size_mb,
        "mission_actions": plain.steps,
    }


def run() -> dict:
    """The ``review`` section as ``cpp-mujoco benchmark`` runs it (the GL backend chosen first)."""
    from cpp_mujoco.review.rendering import configure_gl

    configure_gl()
    return benchmark_review()
