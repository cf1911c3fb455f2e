"""How fast the physics env runs compared with MuJoCo alone, on one core.

``env`` physics steps/s are measured while the env flies a mission (random actions, a fresh
episode whenever one ends); ``raw`` is a Python loop of single ``mj_step`` calls on the same
model in the same process. overhead ratio = env / raw (1.0 would mean the controller, camera,
energy and wind cost nothing); real-time factor = simulated seconds per wall-clock second.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np

from cpp_mujoco.physics.env import MuJoCoEnv


def benchmark_physics(seconds: float = 5.0, map: str = "A", seed: int = 0) -> dict:  # noqa: A002
    """Measure for about ``seconds`` of wall time (split between the two runs)."""
    env = MuJoCoEnv(map=map)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed, options={"budget": 75})
    model, data = env.model, env.data
    budget = seconds / 2

    sim_time, actions, episodes = 0.0, 0, 1
    start = time.perf_counter()
    while time.perf_counter() - start < budget:
        t0 = data.time
        *_, terminated, _, _ = env.step(int(rng.integers(5)))
        sim_time += data.time - t0
        actions += 1
        if terminated:
            env.reset(seed=int(rng.integers(1 << 31)), options={"budget": 75})
            episodes += 1
    env_wall = time.perf_counter() - start
    env_steps = sim_time / model.opt.timestep

    env.reset(seed=seed, options={"budget": 75})  # hovering at cruise altitude
    data.ctrl[:] = data.act[:]
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < budget:
        for _ in range(1000):
            mujoco.mj_step(model, data)
        n += 1000
    raw_wall = time.perf_counter() - start

    env_rate, raw_rate = env_steps / env_wall, n / raw_wall
    return {
        "timestep_s": float(model.opt.timestep),
        "control_rate_hz": env.config.control_rate,
        "camera_rate_hz": env.config.camera_rate,
        "env_steps_per_s": env_rate,
        "raw_steps_per_s": raw_rate,
        "overhead_ratio": env_rate / raw_rate,
        "real_time_factor": env_rate * model.opt.timestep,
        "raw_real_time_factor": raw_rate * model.opt.timestep,
        "actions_per_s": actions / env_wall,
        "episodes": episodes,
        "sim_seconds": sim_time,
    }


if __name__ == "__main__":
    import json
    import sys

    print(json.dumps(benchmark_physics(float(sys.argv[1]) if len(sys.argv) > 1 else 5.0), indent=1))
