"""The evaluation protocol in physics: many MuJoCo episodes, in this process or over workers.

Every episode is :func:`cpp_mujoco.episode.run_episode` on an unwrapped ``MuJoCo-v0`` env, seeded
by its index, so the same episode gives the same numbers in or out of process. The env is built
(and so its options validated) in the calling process first, and the policy is pickled there, so
bad options or an unpicklable policy fail at once with their own message. Each worker then builds
the env and unpickles the policy on its first task — never in the pool's initializer, where a
failure would only break the pool. Any exception in a worker ends the run with that exception (its
message plus a note naming the episode); a worker that dies ends it with ``BrokenProcessPool``.
Results come back per task, so a progress bar can follow. A torch policy runs on one torch thread
per process (the processes share the cores); in this process the caller's count is restored.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import sys
import tempfile
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from cpp_mujoco.episode import EpisodeRecord, run_episode
from cpp_mujoco.io import atomic_write_bytes

_WORKER: dict[str, Any] = {}
TASKS_PER_SUBMIT = 2  # episodes per worker task: small, so a failure ends the run quickly

Task = tuple[int, tuple[int, int], int]  # (episode index, start cell, budget)


def make_env(grid_map, env_kwargs: dict):
    """The unwrapped ``MuJoCo-v0`` env; raises the env's own error for a bad option."""
    import gymnasium as gym

    import cpp_mujoco  # noqa: F401  (registers the envs)

    return gym.make("cpp_mujoco/MuJoCo-v0", map=grid_map, **env_kwargs).unwrapped


@contextmanager
def one_torch_thread() -> Iterator[None]:
    """One torch thread while episodes are flown (a batch of one gains nothing from a thread
    pool on shared cores); the count the caller had is put back afterwards."""
    torch = sys.modules.get("torch")  # a policy that needs torch has imported it
    if torch is None:
        yield
        return
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def _init_worker(job_path: str) -> None:
    """Only store the job file's path (nothing here may fail: see the module docstring)."""
    _WORKER["job_path"] = job_path


def _fly_tasks(tasks: list[Task]) -> list[EpisodeRecord]:
    """Worker entry: build env and policy on first use, then fly ``tasks``."""
    if "env" not in _WORKER:
        with open(_WORKER["job_path"], "rb") as job:
            payload, grid_map, env_kwargs = pickle.load(job)
        _WORKER["policy"] = pickle.loads(payload)
        if "torch" in sys.modules:  # a worker's own process: one thread for good
            sys.modules["torch"].set_num_threads(1)
        _WORKER["env"] = make_env(grid_map, env_kwargs)
    return [fly_one(_WORKER["env"], _WORKER["policy"], task) for task in tasks]


def fly_one(env, policy, task: Task) -> EpisodeRecord:
    """One protocol episode, seeded by its index (the record's ``seed``); an error names it."""
    index, start, budget = task
    try:
        return run_episode(env, policy, seed=index, options={"start": start, "budget": budget})
    except Exception as exc:
        exc.add_note(f"in physics episode {index} (start {start}, budget {budget})")
        raise


def fly_episodes(
    policy,
    grid_map,
    starts: np.ndarray,
    budgets: np.ndarray,
    workers: int | None = None,
    progress: bool = True,
    env_kwargs: dict | None = None,
    env=None,
) -> list[EpisodeRecord]:
    """Fly every (start, budget) episode; results in episode order, one per episode.

    ``env``: an env already built from ``env_kwargs`` (it is closed here); else one is built
    first, so a bad option fails before any worker starts."""
    from tqdm import tqdm

    env_kwargs = dict(env_kwargs or {})
    tasks: list[Task] = [
        (i, (int(s[0]), int(s[1])), int(b))
        for i, (s, b) in enumerate(zip(starts, budgets, strict=True))
    ]
    if env is None:
        env = make_env(grid_map, env_kwargs)  # validates the options here, before any worker
    workers = max(1, min(workers or os.cpu_count() or 1, len(tasks)))
    label = getattr(grid_map, "label", grid_map.name)
    records: list[EpisodeRecord] = []
    bar = tqdm(total=len(tasks), desc=f"MuJoCo {label}", unit="ep", disable=not progress)
    try:
        if workers == 1:
            with one_torch_thread():
                for task in tasks:
                    records.append(fly_one(env, policy, task))
                    bar.update()
        else:
            env.close()
            payload = pickle.dumps(policy)  # an unpicklable policy fails here, in the caller
            records = _fly_in_pool(payload, grid_map, env_kwargs, tasks, workers, bar)
    finally:
        env.close()
        bar.close()
    records.sort(key=lambda r: r.seed)
    if [r.seed for r in records] != list(range(len(tasks))):
        raise RuntimeError(f"physics run returned {len(records)} of {len(tasks)} episodes")
    return records


def _fly_in_pool(payload, grid_map, env_kwargs, tasks, workers, bar) -> list[EpisodeRecord]:
    """The workers get the policy, map and options from a job file, not as initializer
    arguments: spawn writes those into a pipe before the child reads them, and a child that dies
    first (a user script without the ``__main__`` guard re-runs itself there) leaves that write
    blocked forever once it exceeds the pipe's 64 KiB — a network's weights do. A path never
    does, so the dead child surfaces as ``BrokenProcessPool``."""
    ctx = mp.get_context("spawn")  # torch's threads do not survive fork
    with tempfile.TemporaryDirectory(prefix="cpp_mujoco_workers_") as folder:
        job = Path(folder) / "job.pickle"
        atomic_write_bytes(job, pickle.dumps((payload, grid_map, env_kwargs)))
        return _run_pool(ctx, str(job), tasks, workers, bar)


def _run_pool(ctx, job: str, tasks, workers, bar) -> list[EpisodeRecord]:
    records: list[EpisodeRecord] = []
    pool = ProcessPoolExecutor(workers, ctx, _init_worker, (job,))
    try:
        pending: set[Future] = {
            pool.submit(_fly_tasks, tasks[i : i + TASKS_PER_SUBMIT])
            for i in range(0, len(tasks), TASKS_PER_SUBMIT)
        }
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                batch = future.result()  # re-raises the worker's exception
                records.extend(batch)
                bar.update(len(batch))
    except BrokenProcessPool as exc:
        exc.add_note(
            "a physics worker died before it returned: killed (out of memory?), or the calling "
            "script runs its work at import: workers are spawned and import the main module, "
            'so put the script\'s work under `if __name__ == "__main__":`'
        )
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    return records


def records_to_arrays(records: list[EpisodeRecord]) -> dict[str, Any]:
    """Per-episode columns for an ``EvaluationResult`` (trajectories padded with -1)."""
    length = max(len(r.cells) for r in records)
    trajectories = np.full((len(records), length), -1, dtype=np.int64)
    for i, r in enumerate(records):
        trajectories[i, : len(r.cells)] = r.cells

    def column(values, dtype=float) -> np.ndarray:
        return np.array(list(values), dtype=dtype)

    def final(key: str, dtype=float) -> np.ndarray:
        return column((r.info[key] for r in records), dtype)

    return {
        "landed": final("landed", bool),
        "coverage": final("coverage_ratio"),
        "steps": column((r.steps for r in records), np.int64),
        "returns": column(r.total_reward for r in records),
        "trajectories": trajectories,
        "physics": {
            "energy_used_j": final("energy_used_j"),
            "flight_time_s": final("flight_time_s"),
            "nfz_violations": final("nfz_violations", np.int64),
            "max_track_error_m": final("max_track_error_m"),
            "guard_takeovers": final("guard_takeovers", np.int64),
            "crashed": final("crashed", bool),
            "crash_reason": np.array([r.info["crash_reason"] or "" for r in records]),
        },
    }
