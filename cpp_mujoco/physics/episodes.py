"""Many physics episodes of the evaluation protocol, spread over worker processes.

Each worker builds the MuJoCo env and unpickles the policy once, then flies the episodes it is
handed; results come back per episode, so a progress bar can follow and an interrupted run loses
only the episodes in flight.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

_WORKER: dict[str, Any] = {}


@dataclass
class EpisodeRecord:
    index: int
    landed: bool
    crashed: bool
    coverage: float
    steps: int
    total_reward: float
    energy_used_j: float
    flight_time_s: float
    nfz_violations: int
    crash_reason: str | None
    cells: list[int]


def _init_worker(policy, grid_map, env_kwargs: dict) -> None:
    import gymnasium as gym

    import cpp_mujoco  # noqa: F401

    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # pragma: no cover - torch is a dependency
        pass
    _WORKER["env"] = gym.make("cpp_mujoco/MuJoCo-v0", map=grid_map, **env_kwargs).unwrapped
    _WORKER["policy"] = policy


def _fly(task: tuple[int, tuple[int, int], int]) -> EpisodeRecord:
    index, start, budget = task
    env, policy = _WORKER["env"], _WORKER["policy"]
    obs, info = env.reset(seed=index, options={"start": start, "budget": budget})
    width = env.grid_map.shape[1]
    cells = [start[0] * width + start[1]]
    total, terminated = 0.0, False
    while not terminated:
        action = int(np.asarray(policy.act({k: np.asarray(v)[None] for k, v in obs.items()}))[0])
        obs, reward, terminated, _, info = env.step(action)
        total += reward
        cells.append(info["position"][0] * width + info["position"][1])
    return EpisodeRecord(
        index=index,
        landed=info["landed"],
        crashed=info["crashed"],
        coverage=info["coverage_ratio"],
        steps=len(cells) - 1,
        total_reward=total,
        energy_used_j=info["energy_used_j"],
        flight_time_s=info["flight_time_s"],
        nfz_violations=info["nfz_violations"],
        crash_reason=info["crash_reason"],
        cells=cells,
    )


def fly_episodes(
    policy,
    grid_map,
    starts: np.ndarray,
    budgets: np.ndarray,
    workers: int | None = None,
    progress: bool = True,
    env_kwargs: dict | None = None,
) -> list[EpisodeRecord]:
    """Fly every (start, budget) episode; results in episode order."""
    from tqdm import tqdm

    env_kwargs = dict(env_kwargs or {})
    tasks = [
        (i, (int(s[0]), int(s[1])), int(b))
        for i, (s, b) in enumerate(zip(starts, budgets, strict=True))
    ]
    workers = max(1, min(workers or os.cpu_count() or 1, len(tasks)))
    bar = tqdm(total=len(tasks), desc=f"MuJoCo {grid_map.name}", unit="ep", disable=not progress)
    records: list[EpisodeRecord] = []
    if workers == 1:
        _init_worker(policy, grid_map, env_kwargs)
        try:
            for task in tasks:
                records.append(_fly(task))
                bar.update()
        finally:
            _WORKER.clear()
    else:
        ctx = mp.get_context("spawn")  # torch's threads do not survive fork
        with ctx.Pool(workers, _init_worker, (policy, grid_map, env_kwargs)) as pool:
            for record in pool.imap_unordered(_fly, tasks, chunksize=4):
                records.append(record)
                bar.update()
    bar.close()
    return sorted(records, key=lambda r: r.index)
