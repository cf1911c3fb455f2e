"""The evaluation protocol in physics: many MuJoCo episodes, in this process or over workers.

The episodes are flown in batches (:func:`chunks`: ordered by budget, so a batch's episodes last
about as long) by the batched ``MuJoCo-v0`` (:mod:`~cpp_mujoco.physics.envs.vector`), each
episode seeded by its index exactly as a single env's episode — so the same episode gives the
same numbers in or out of process, in any batch, on any engine (``tests/test_episode_runner.py``
compares it with :func:`~cpp_mujoco.protocol.episode.run_episode` on a single env). A stateful
policy is
started once per batch, seeded with its first episode's index, as in the grid protocol.
A single env is built (and so the options validated) in the calling process first, and the
policy is pickled there, so bad options or an unpicklable policy fail at once with their own
message.

Out of process, the work is a :class:`Job` (the pickled policy, the map, the env options) and
chunks of tasks; :func:`fly_chunk` — chunk in, records out — is what every worker runs, whichever
engine carries it. A worker builds its envs and unpickles the policy on its first chunk of a job
and keeps them for the job's later chunks (:func:`worker_state`); never in a pool's initializer,
where a failure would only break the pool.

Two engines carry the chunks: ``"local"``, a spawn process pool on this machine, and ``"ray"``
(:mod:`cpp_mujoco.protocol.ray_engine`), a local Ray runtime or a cluster. The pool stays next to
Ray because Ray is an optional, heavy extra (hundreds of MB, seconds to start a runtime): the base
install must still fly the protocol on every core, and a one-machine run gains nothing from Ray.
On both, any exception in a worker ends the run with that exception (its message plus a note
naming the batch's episodes); a pool worker that dies ends the run with ``BrokenProcessPool``, a Ray
worker that dies has its chunk retried. Results come back per chunk, so a progress bar can
follow. A torch policy runs on one torch thread per process (the processes share the cores); in
this process the caller's count is restored.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import tempfile
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from cpp_mujoco.protocol.episode import EpisodeRecord
from cpp_mujoco.protocol.physics_tasks import (
    Job,
    Task,
    VectorEnvs,
    chunk_count,
    chunks,
    fly_chunk,
    fly_tasks,
    make_env,
    one_torch_thread,
)
from cpp_mujoco.protocol.ray_engine import fly_on_ray
from cpp_mujoco.util.io import atomic_write_bytes

ENGINES = ("local", "ray")  # this machine's process pool, or Ray (an optional extra)


def fly_episodes(
    policy,
    grid_map,
    starts: np.ndarray,
    budgets: np.ndarray,
    workers: int | None = None,
    progress: bool = True,
    env_kwargs: dict | None = None,
    env=None,
    engine: str = "local",
    ray_address: str | None = None,
) -> list[EpisodeRecord]:
    """Fly every (start, budget) episode; results in episode order, one per episode.

    ``env``: an env already built from ``env_kwargs`` (it is closed here); else one is built
    first, so a bad option fails before any worker starts. ``engine="local"``: ``workers``
    processes here (default: all cores; 1 flies in this process); ``"ray"``: Ray tasks on the
    runtime at ``ray_address`` (else ``RAY_ADDRESS``, else a local one with ``workers`` CPUs)."""
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r}; available: {', '.join(ENGINES)}")
    if ray_address is not None and engine != "ray":
        raise ValueError("ray_address needs engine='ray'")
    env_kwargs = dict(env_kwargs or {})
    tasks: list[Task] = [
        (i, (int(s[0]), int(s[1])), int(b))
        for i, (s, b) in enumerate(zip(starts, budgets, strict=True))
    ]
    if env is None:
        env = make_env(grid_map, env_kwargs)  # validates the options here, before any worker
    workers = max(1, min(workers or os.cpu_count() or 1, len(tasks)))
    work = chunks(tasks, chunk_count(len(tasks)))
    label = getattr(grid_map, "label", grid_map.name)
    records: list[EpisodeRecord] = []
    bar = tqdm(total=len(tasks), desc=f"MuJoCo {label}", unit="ep", disable=not progress)
    try:
        if engine == "local" and workers == 1:
            envs = VectorEnvs(grid_map, env_kwargs)
            try:
                with one_torch_thread():
                    for chunk in work:
                        records += fly_tasks(envs, policy, chunk)
                        bar.update(len(chunk))
            finally:
                envs.close()
        else:
            env.close()
            job = Job(pickle.dumps(policy), grid_map, env_kwargs)  # unpicklable: fails here
            if engine == "ray":
                records = fly_on_ray(job, work, bar, workers, ray_address)
            else:
                records = _fly_in_pool(job, work, workers, bar)
    finally:
        env.close()
        bar.close()
    records.sort(key=lambda r: r.seed)
    if [r.seed for r in records] != list(range(len(tasks))):
        raise RuntimeError(f"physics run returned {len(records)} of {len(tasks)} episodes")
    return records


_POOL_JOB: dict[str, Any] = {}  # a pool worker's job file, and the job once read


def _init_worker(job_path: str) -> None:
    """Only store the job file's path (nothing here may fail: see the module docstring)."""
    _POOL_JOB["path"] = job_path


def _pool_chunk(tasks: list[Task]) -> list[EpisodeRecord]:
    """A pool worker's task: the job comes from its file (read once per process)."""
    if "job" not in _POOL_JOB:
        with open(_POOL_JOB["path"], "rb") as file:
            _POOL_JOB["job"] = pickle.load(file)
    return fly_chunk(_POOL_JOB["job"], tasks)


def _fly_in_pool(job: Job, work: list[list[Task]], workers: int, bar) -> list[EpisodeRecord]:
    """The workers get the job (policy, map and options) from a file, not as initializer
    arguments: spawn writes those into a pipe before the child reads them, and a child that dies
    first (a user script without the ``__main__`` guard re-runs itself there) leaves that write
    blocked forever once it exceeds the pipe's 64 KiB — a network's weights do. A path never
    does, so the dead child surfaces as ``BrokenProcessPool``."""
    ctx = mp.get_context("spawn")  # torch's threads do not survive fork
    with tempfile.TemporaryDirectory(prefix="cpp_mujoco_workers_") as folder:
        path = Path(folder) / "job.pickle"
        atomic_write_bytes(path, pickle.dumps(job))
        return _run_pool(ctx, str(path), work, workers, bar)


def _run_pool(ctx, job: str, work, workers, bar) -> list[EpisodeRecord]:
    records: list[EpisodeRecord] = []
    pool = ProcessPoolExecutor(workers, ctx, _init_worker, (job,))
    try:
        pending: set[Future] = {pool.submit(_pool_chunk, chunk) for chunk in work}
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
