"""Demonstrations from a reference planner, for DQfD's large-margin loss (Hester et al. 2018).

The planner (default: the beam search) flies every episode of the training distribution — every
landing cell × every budget min..max, the set the protocol evaluates (``protocol_budgets``) —
once, through the protocol's own batched loop (``evaluate``'s ``on_step`` hook). Its transitions
are kept in a ``ReplayBuffer`` with one column per episode, so the n-step returns of
demonstration samples are read exactly as for the agent's own experience. The grid is
deterministic and so is the planner: the memory is rebuilt, not checkpointed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpp_mujoco.agent.replay import ReplayBuffer
from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.maps import GridMap
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets, protocol_episodes


@dataclass
class Demonstrations:
    memory: ReplayBuffer  # one column per demonstrated episode
    rows: np.ndarray  # (T,) row of each recorded transition …
    episodes: np.ndarray  # (T,) … and its column
    landing_ratio: float
    coverage_ratio: float

    def __len__(self) -> int:
        return self.rows.size

    def sample(self, batch_size: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Uniformly drawn demonstrated n-step transitions (``ReplayBuffer.transitions``)."""
        i = rng.integers(self.rows.size, size=batch_size)
        return self.memory.transitions(self.rows[i], self.episodes[i])


def record_demonstrations(
    grid_map: GridMap,
    config: GridConfig,
    planner,
    n_step: int,
    gamma: float,
    budgets: list[int] | None = None,
) -> Demonstrations:
    """Fly ``planner`` over every (landing cell, budget) pair and keep every transition
    (``budgets``: default every budget of ``config``; the general agent's pool takes fewer)."""
    budgets = protocol_budgets(config) if budgets is None else budgets
    k = len(protocol_episodes(grid_map, budgets)[0])
    steps = []  # (obs, actions, reward, done, active) of each batched step, stored afterwards

    def record(obs, actions, outcome, active) -> None:
        steps.append((obs, actions, outcome.reward, outcome.terminated | ~active, active))

    result = evaluate(planner, grid_map, budgets=budgets, config=config, on_step=record)
    # one row per step flown: in calm air an episode takes at most max_budget steps, in the
    # wind option more (a downwind move costs less than a unit), so the memory is sized after
    # the flight, never wrapping round
    memory = ReplayBuffer((len(steps) + n_step + 2) * k, k, grid_map.layers, n_step, gamma)
    for obs, actions, reward, done, _ in steps:
        memory.add(obs, actions, reward, done)
    rows, episodes = np.nonzero(np.stack([active for *_, active in steps]))
    return Demonstrations(memory, rows, episodes, result.landing_ratio, result.coverage_ratio)
