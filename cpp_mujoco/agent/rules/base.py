"""What a policy rule is: a named, versioned narrowing of the actions a greedy agent may take.

An agent is a network plus an ordered list of rules. At each step every rule, in order, narrows
the batch's allowed actions (N, 5 bool); the agent then takes the argmax of its Q-values among
what is left. A *hard* rule (the return mask: the way home stays paid) is never undone; a soft
rule that would leave a row with no action falls back to ``floor``, the set after the last hard
rule. Results name each rule by its versioned ``rule`` string, so a changed rule is a new name.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar, Protocol

import numpy as np

Observation = dict[str, np.ndarray]
QValues = Callable[[Observation], np.ndarray]  # a batch of observations → (N, 5)


class Rule(Protocol):
    """One rule of a greedy agent (:class:`~cpp_mujoco.agent.policy.GreedyAgent`)."""

    name: ClassVar[str]  # what ``--rule`` and the agent file call it
    rule: ClassVar[str]  # the versioned rule string results record
    hard: ClassVar[bool]  # later rules fall back to its set, never past it

    def reset(self, num_episodes: int) -> None:
        """A new batch of ``num_episodes`` episodes starts (a rule with memory forgets it)."""

    def allowed(
        self, obs: Observation, allowed: np.ndarray, floor: np.ndarray, q_values: QValues
    ) -> np.ndarray:
        """``allowed`` (N, 5 bool) narrowed by the rule for this step's observations;
        ``q_values`` reads the agent's network (for a rule that ranks actions)."""

    def identity(self) -> dict[str, Any]:
        """What results record of the rule (its rule string, its parameters)."""


class Stateless:
    """A rule that keeps nothing between steps: an episode start changes nothing."""

    def reset(self, num_episodes: int) -> None:
        pass
