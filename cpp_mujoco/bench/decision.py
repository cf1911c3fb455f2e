"""Decision time: how long one UAV's policy takes to choose an action on one core (one torch
thread), per policy and map size — what a computer on board has to afford (the ``decision``
section of ``cpp-mujoco benchmark``).

Each policy flies whole single-UAV episodes on the first map of heldout16-v1 and heldout32-v1
(the city agent: of city32-v1; budgets spread over the size class); every ``act`` call is
timed. The mean is the cost per action; the maximum is the slowest single decision (beam search
plans its whole mission at the first action and then follows it)."""

from __future__ import annotations

import time

import numpy as np
import torch

from cpp_mujoco.agent import GENERAL_AGENT, GENERAL_CITY_AGENT, load_agent
from cpp_mujoco.agent.value_beam import ValueBeamAgent
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.map_sets.sets import load_map_set
from cpp_mujoco.map_sets.size_classes import budget_range, size_config
from cpp_mujoco.planners import BeamSearchPlanner, SafeGreedyPlanner
from cpp_mujoco.protocol.episode import run_batch
from cpp_mujoco.protocol.policy import start_episodes


class _Timed:
    """A policy whose every ``act`` is timed (one UAV: a batch of one)."""

    def __init__(self, policy):
        self.policy, self.seconds = policy, []

    def reset(self, num_episodes: int, seed: int | None = None) -> None:
        start_episodes(self.policy, num_episodes, seed)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        start = time.perf_counter()
        actions = self.policy.act(obs)
        self.seconds.append(time.perf_counter() - start)
        return actions


def decision_times(policy, size: int, episodes: int = 4, family: str = "heldout") -> np.ndarray:
    """Seconds of each decision over ``episodes`` single-UAV episodes on the first map of the
    family's set of that size (``heldout``: heldout16-v1, heldout32-v1; ``city``: city32-v1)."""
    grid_map = load_map_set(f"{family}{size}-v1", first=1)[0]
    low, high = budget_range(size)
    timed = _Timed(policy)
    for k, budget in enumerate(np.linspace(low, high, episodes).round().astype(int)):
        mdp = GridMDP(grid_map, 1, size_config(size))
        mdp.reset(np.random.default_rng(k), budget=np.array([budget]))
        run_batch(mdp, timed, seed=k)
    return np.array(timed.seconds)


def run() -> dict:
    """The ``decision`` section as ``cpp-mujoco benchmark`` runs it."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        agent = load_agent(GENERAL_AGENT)
        policies = {
            "general": agent,  # with its rules: return, revisit, finish and progress masks
            "general_network_alone": agent.with_rules(["return-mask"]),
            "general_value_beam": ValueBeamAgent(agent),  # plans at its first decision
            "safe_greedy": SafeGreedyPlanner(),
            "beam_search": BeamSearchPlanner(),
        }
        # (key, policy, size, the family of the map set it flies on)
        runs = [(name, policy, size, "heldout") for size in (16, 32)
                for name, policy in policies.items()]  # fmt: skip
        # the city agent with its rules (symmetric Q: eight readings of the network a step)
        runs.append(("general_city", load_agent(GENERAL_CITY_AGENT), 32, "city"))
        result = {"torch_threads": 1}
        for name, policy, size, family in runs:
            seconds = decision_times(policy, size, family=family)
            result[f"{name}_{size}x{size}_ms_mean"] = float(seconds.mean() * 1000)
            result[f"{name}_{size}x{size}_ms_max"] = float(seconds.max() * 1000)
        return result
    finally:
        torch.set_num_threads(threads)
