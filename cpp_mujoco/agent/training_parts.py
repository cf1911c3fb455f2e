"""The parts one training run is built from; the loop (:class:`~cpp_mujoco.agent.train.Trainer`)
is the same for every run.

A per-map run (:func:`~cpp_mujoco.agent.map_training.map_parts`) and the general agent's run on a
pool of generated maps (:func:`~cpp_mujoco.agent.general_training.general_parts`) are two sets of
these parts: a map source, a vector env, a replay memory, a network, and optionally a guide planner
and demonstrations. The rules the agent acts with come from the config (``rule_names``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import gymnasium as gym
import torch

from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.protocol.policy import Policy


class MapSource(Protocol):
    """Where a run's maps come from and how its agent is judged: one map or a pool of maps."""

    agent_name: str  # the greedy agent's name in evaluations
    log_title: str  # the title of log.csv's figure (training.png)
    map_name: str  # the agent file's "map"
    digest: str  # the agent file's "map_digest": the cells trained on
    judged_on: str  # what the evaluations fly, in words: "evaluation", "validation"

    def budget_step(self, full: bool) -> int:
        """The evaluation's budget step (``full``: the final evaluation's)."""

    def evaluate(self, agent: Policy, budget_step: int) -> Any:
        """The greedy agent's protocol figures (``landing_ratio``, ``coverage_ratio``,
        ``returns``, ``conditions``, ``to_json``)."""

    def complete(self, result: Any, budget_step: int) -> None:
        """Add to a final evaluation what it shows beside the agent (e.g. a reference planner)."""

    def payload(self) -> dict:
        """Keys the agent file holds besides the agent's own (e.g. the map pools)."""

    def read_resumable(self, path: Path, config: TrainConfig) -> tuple[dict, TrainConfig]:
        """The checkpoint at ``path``, refused (``CheckpointError``) unless it continues this run
        with ``config``; and the config to continue with (the run's own where it must keep it)."""


@dataclass
class TrainingParts:
    """What a run trains on and with."""

    maps: MapSource
    env: gym.vector.VectorEnv  # flies the training episodes (``autoreset_mode="SameStep"``)
    replay: Any  # ReplayBuffer or MultiMapReplay: add, sample, can_sample, state_dict
    network: Callable[[TrainConfig], torch.nn.Module]  # a fresh network, starting weights loaded
    guide: Policy | None = None  # drives the first envs while guide_fraction decays
    demos: Any = None  # demonstrations mixed into each minibatch (demo_fraction), or None
    fused_adam: bool = False  # Adam's fused step: the same update, less Python per step
