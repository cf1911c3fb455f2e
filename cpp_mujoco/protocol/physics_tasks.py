"""What a worker of the physics protocol runs: a :class:`Job` (the pickled policy, the map, the
env options) and chunks of its tasks, flown by :func:`fly_chunk` — chunk in, records out —
whichever engine carries them (:mod:`~cpp_mujoco.protocol.physics_engines`' process pool or
:mod:`~cpp_mujoco.protocol.ray_engine`).
"""

from __future__ import annotations

import pickle
import sys
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.protocol.episode import EpisodeRecord, run_vector_episodes

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


def make_env(grid_map, env_kwargs: dict):
    """The unwrapped ``MuJoCo-v0`` env; raises the env's own error for a bad option."""
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
            from cpp_mujoco.physics.envs.vector import MuJoCoVectorEnv  # heavy: MuJoCo

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
