"""The evaluation protocol in physics: many MuJoCo episodes, in this process or over workers.

The episodes are flown in batches (:func:`chunks`: ordered by budget, so a batch's episodes last
about as long) by the batched ``MuJoCo-v0`` (:mod:`~cpp_mujoco.physics.envs.vector`), each
episode seeded by its index exactly as a single env's episode — so the same episode gives the
same numbers in or out of process, in any batch, on any engine (``tests/test_episode_runner.py``
compares it with :func:`~cpp_mujoco.episode.run_episode` on a single env). A stateful policy is
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
import sys
import tempfile
import uuid
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cpp_mujoco.episode import EpisodeRecord, run_vector_episodes
from cpp_mujoco.io import atomic_write_bytes

ENGINES = ("local", "ray")  # this machine's process pool, or Ray (an optional extra)
# A worker's task is a chunk of episodes flown together in one batched env. The control tick
# costs a fixed ≈ 0.5 ms of numpy calls plus a share per drone, so bigger batches fly more
# episodes per second (one core, 288 episodes of map A: batches of 72 took 1.4× as long as one
# batch of 288). A run is cut into chunks of EPISODES_PER_CHUNK episodes on average, whatever
# the workers: a policy's batches, so a stochastic policy's draws, never depend on the engine
# or the worker count (the protocol on map A: 10 chunks, 5 per worker on 2 cores)
EPISODES_PER_CHUNK = 192
MIN_CHUNKS, MIN_EPISODES_PER_CHUNK = 4, 48

Task = tuple[int, tuple[int, int], int]  # (episode index, start cell, budget)


@dataclass(frozen=True)
class Job:
    """What every chunk of one run needs: made once in the caller, sent to each worker once.

    ``key`` names the job, so a worker reused for a later run (a Ray worker, a sweep's next
    wind) rebuilds its env and policy instead of flying the new chunks with the old ones."""

    payload: bytes  # the pickled policy
    grid_map: Any  # GridMap
    env_kwargs: dict
    key: str = field(default_factory=lambda: uuid.uuid4().hex)


_STATE: dict[str, Any] = {}  # this worker process's job key, env and policy
_POOL_JOB: dict[str, Any] = {}  # a pool worker's job file, and the job once read


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


class VectorEnvs:
    """A worker's batched envs of one job, one per batch size (a run's last batch is smaller):
    compiled once, reset for every batch."""

    def __init__(self, grid_map, env_kwargs: dict):
        self.grid_map, self.env_kwargs = grid_map, env_kwargs
        self._envs: dict[int, Any] = {}

    def get(self, n: int):
        if n not in self._envs:
            from cpp_mujoco.physics.envs.vector import MuJoCoVectorEnv

            self._envs[n] = MuJoCoVectorEnv(
                num_envs=n, map=self.grid_map, autoreset_mode="Disabled", **self.env_kwargs
            )
        return self._envs[n]

    def close(self) -> None:
        for env in self._envs.values():
            env.close()
        self._envs.clear()


def worker_state(job: Job) -> tuple[VectorEnvs, Any]:
    """(envs, policy) of ``job`` in this worker process: built on its first chunk, kept for the
    rest; a new job closes the old envs first (one job's envs at a time per process)."""
    if _STATE.get("key") != job.key:
        if "envs" in _STATE:
            _STATE.pop("envs").close()
        _STATE.clear()
        policy = pickle.loads(job.payload)
        if "torch" in sys.modules:  # a worker's own process: one thread for good
            sys.modules["torch"].set_num_threads(1)
        _STATE.update(key=job.key, policy=policy, envs=VectorEnvs(job.grid_map, job.env_kwargs))
    return _STATE["envs"], _STATE["policy"]


def fly_chunk(job: Job, tasks: list[Task]) -> list[EpisodeRecord]:
    """A worker's entry, on every engine: fly ``tasks`` of ``job`` (chunk in, records out)."""
    envs, policy = worker_state(job)
    return fly_tasks(envs, policy, tasks)


def fly_tasks(envs: VectorEnvs, policy, tasks: list[Task]) -> list[EpisodeRecord]:
    """``tasks`` flown together in one batched env, episode i seeded by its index as a single
    env's would be; the policy starts the batch seeded by its first episode's index. An error
    names the batch's episodes."""
    try:
        return run_vector_episodes(
            envs.get(len(tasks)), policy, seeds=[index for index, _, _ in tasks],
            options={"start": np.array([s for _, s, _ in tasks]),
                     "budget": np.array([b for _, _, b in tasks])},
            batch_seed=tasks[0][0],
        )  # fmt: skip
    except Exception as exc:
        episodes = ", ".join(f"{i} (start {s}, budget {b})" for i, s, b in tasks[:4])
        more = f" and {len(tasks) - 4} more" if len(tasks) > 4 else ""
        exc.add_note(f"in a batch of physics episodes: {episodes}{more}")
        raise


def chunk_count(episodes: int) -> int:
    """How many chunks a run of ``episodes`` is cut into (see :data:`EPISODES_PER_CHUNK`): at
    least :data:`MIN_CHUNKS` of at least :data:`MIN_EPISODES_PER_CHUNK`, so a small run still
    spreads over a few workers."""
    few = min(MIN_CHUNKS, -(-episodes // MIN_EPISODES_PER_CHUNK))
    return max(1, few, round(episodes / EPISODES_PER_CHUNK))


def chunks(tasks: list[Task], count: int) -> list[list[Task]]:
    """``tasks`` ordered by budget, cut into ``count`` chunks of (nearly) equal size: episodes
    of similar budgets last about as long, so a batch's drones finish together instead of most
    of them waiting for one long episode. The chunks of the largest budgets come first: the
    longest start first and the short ones fill the workers' ends. (Equal budget sums are no
    better: a policy lands long budgets early, so their chunks fly fewer steps.) The same chunks
    on every engine; a deterministic policy flies the same episode in any chunk, a stochastic
    one's draws depend on its batch."""
    ordered = sorted(tasks, key=lambda task: (task[2], task[0]))
    bounds = np.linspace(0, len(ordered), count + 1).round().astype(int).tolist()
    return [ordered[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True)][::-1]


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
    from tqdm import tqdm

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
                from cpp_mujoco.protocol.ray_engine import fly_on_ray

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
