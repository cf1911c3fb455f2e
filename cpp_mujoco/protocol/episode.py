"""The one episode loop: a policy plays episodes to their end, hooks see every step.

Two forms of the same loop, because there are two kinds of env:

* :func:`run_episode` — one gymnasium env (``Grid-v0`` or ``MuJoCo-v0``), one episode: the
  physics protocol's workers and ``fly`` run it; ``fly`` adds its recording through
  ``on_start``/``on_step`` (and its cameras through the env's ``on_frame``).
* :func:`run_batch` — a batched :class:`GridMDP`, all its episodes at once: the grid protocol
  (``evaluate``), the planners' rollouts and the recorded demonstrations run it.
* :func:`run_vector_episodes` — a gymnasium vector env (the batched ``MuJoCo-v0``), one episode
  per env, seeded and started each as :func:`run_episode` would: the physics protocol's workers.

Both start the policy's episodes first (:func:`~cpp_mujoco.protocol.policy.start_episodes`), so a
stateful
policy (a planner's plans) never carries a plan from one episode into the next.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.mdp import GridMDP, StepOutcome
from cpp_mujoco.protocol.policy import Observation, act_batch, act_one, start_episodes

# run_episode's hooks: on_start(obs, info) after the reset; on_step(action, obs, reward, info)
OnStart = Callable[[Observation, dict], None]
OnStep = Callable[[int, Observation, float, dict], None]
# run_batch's hook: on_step(observation, actions, outcome, active) after every batched step
OnBatchStep = Callable[[Observation, np.ndarray, StepOutcome, np.ndarray], None]


@dataclass
class EpisodeRecord:
    """One episode of a single env: where it started, what the policy did, how it ended."""

    seed: int | None
    start: tuple[int, int]
    budget: int
    actions: list[int] = field(default_factory=list)
    cells: list[int] = field(default_factory=list)  # flat cells visited, the start first
    total_reward: float = 0.0
    info: dict[str, Any] = field(default_factory=dict)  # the env's info after the last step

    @property
    def steps(self) -> int:
        return len(self.actions)


def run_episode(
    env,
    policy,
    *,
    seed: int | None,
    options: dict[str, Any] | None = None,
    on_start: OnStart | None = None,
    on_step: OnStep | None = None,
) -> EpisodeRecord:
    """Reset ``env`` with ``seed`` and ``options``, tell ``policy`` an episode starts (seeded the
    same), and play it greedily to termination."""
    obs, info = env.reset(seed=seed, options=options)
    start_episodes(policy, 1, seed=seed)
    width = env.grid_map.shape[1]
    row, col = info["position"]
    record = EpisodeRecord(seed, (row, col), info["budget"], cells=[row * width + col])
    if on_start is not None:
        on_start(obs, info)
    terminated = False
    while not terminated:
        action = act_one(policy, obs)
        obs, reward, terminated, _, info = env.step(action)
        record.actions.append(action)
        record.cells.append(info["position"][0] * width + info["position"][1])
        record.total_reward += reward
        if on_step is not None:
            on_step(action, obs, reward, info)
    record.info = info
    return record


def run_batch(
    mdp: GridMDP, policy, *, seed: int | None = None, on_step: OnBatchStep | None = None
) -> None:
    """Play every live episode of ``mdp`` to its end (one batched ``act`` per step); ``seed``
    names the batch for the policy's episode start. Finished episodes are given ``LAND``, which
    the MDP ignores for them; ``on_step`` sees each step's actions and the ``active`` mask."""
    start_episodes(policy, mdp.num_envs, seed=seed)
    while not mdp.done.all():
        active = ~mdp.done
        obs = mdp.observation()
        actions = np.asarray(act_batch(policy, obs, active), dtype=np.int64).reshape(-1)
        if actions.shape != active.shape:  # never broadcast one action over the batch
            raise ValueError(f"policy gave {actions.size} actions for {active.size} episodes")
        actions = np.where(active, actions, LAND)
        outcome = mdp.step(actions, active=active)
        if on_step is not None:
            on_step(obs, actions, outcome, active)


def run_vector_episodes(
    venv, policy, *, seeds: list[int], options: dict[str, Any], batch_seed: int | None = None
) -> list[EpisodeRecord]:
    """One episode per env of ``venv`` (autoreset disabled), env i seeded ``seeds[i]`` with the
    per-env reset ``options`` (``start`` (N, 2), ``budget`` (N,)): the records
    :func:`run_episode` gives for the same seeds and options with a deterministic policy.
    ``batch_seed`` names the batch for the policy's episode start."""
    obs, info = venv.reset(seed=list(seeds), options=options)
    n = venv.num_envs
    start_episodes(policy, n, seed=batch_seed)
    width = venv.grid_map.shape[1]
    records = [
        EpisodeRecord(s, (int(r), int(c)), int(b), cells=[int(r) * width + int(c)])
        for s, (r, c), b in zip(seeds, info["position"], info["budget"], strict=True)
    ]
    done = np.zeros(n, dtype=bool)
    while not done.all():
        actions = np.asarray(act_batch(policy, obs, ~done), dtype=np.int64).reshape(-1)
        if actions.shape != (n,):  # never broadcast one action over the batch
            raise ValueError(f"policy gave {actions.size} actions for {n} episodes")
        actions = np.where(done, LAND, actions)  # the env ignores finished episodes
        obs, reward, terminated, _, info = venv.step(actions)
        cells = info["position"][:, 0] * width + info["position"][:, 1]
        for i in np.flatnonzero(~done).tolist():
            record = records[i]
            record.actions.append(int(actions[i]))
            record.cells.append(int(cells[i]))
            record.total_reward += float(reward[i])
            if terminated[i]:
                record.info = _info_of(info, i)
        done |= terminated
    return records


def _info_of(info: dict[str, np.ndarray], i: int) -> dict[str, Any]:
    """Env ``i``'s entry of a vector env's info, as the single env's info (Python scalars)."""
    out: dict[str, Any] = {}
    for key, values in info.items():
        if key.startswith("_"):
            continue
        value = values[i]
        out[key] = (
            tuple(int(v) for v in value)
            if key == "position"
            else (value.item() if isinstance(value, np.generic) else value)
        )
    return out
