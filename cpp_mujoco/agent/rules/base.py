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


def _shared(value: np.ndarray, unbatched: int) -> bool:
    """Whether a map-like entry is one for the whole batch: unbatched, or a broadcast view."""
    return value.ndim == unbatched or value.shape[0] <= 1 or value.strides[0] == 0


def map_groups(obs: Observation) -> list[tuple[Observation, np.ndarray]]:
    """The batch's distinct maps, each as an observation part (``map`` (3,H,W), and its
    ``obstacle`` (H,W) where the observation has the layer) with the rows flown on it: the
    rules that read a map's graph (:func:`~cpp_mujoco.grid.graph.graph_from_observation`)
    build it once per map, obstacles included."""
    layers = np.asarray(obs["map"])
    n = int(np.shape(obs["coverage"])[0])
    if not n:
        return []
    every = np.arange(n)
    if "obstacle" in obs:
        obstacle = np.asarray(obs["obstacle"])
        if _shared(layers, 3) and _shared(obstacle, 2):
            one = layers if layers.ndim == 3 else layers[0]
            return [({"map": one, "obstacle": obstacle if obstacle.ndim == 2 else obstacle[0]},
                     every)]  # fmt: skip
        cells = obstacle.shape[-2:]
        layers = np.concatenate(
            [
                np.broadcast_to(layers, (n, 3, *cells)),
                np.broadcast_to(obstacle, (n, *cells))[:, None],
            ],
            axis=1,
        )
    elif layers.ndim == 3:
        return [({"map": layers}, every)]
    flat = layers.reshape(n, -1)
    if flat.size and (flat == flat[:1]).all():
        # one map in every row (a protocol's batch): np.unique's row sort would cost more than
        # the whole decision
        groups = [(layers[0], every)]
    else:
        _, first, which = np.unique(flat, axis=0, return_index=True, return_inverse=True)
        groups = [(layers[f], np.flatnonzero(which.reshape(-1) == k)) for k, f in enumerate(first)]
    return [(_part(one), rows) for one, rows in groups]


def _part(layers: np.ndarray) -> Observation:
    """(3,H,W) map layers, or (4,H,W) with the obstacle layer last → an observation part."""
    return {"map": layers[:3], **({"obstacle": layers[3]} if layers.shape[0] > 3 else {})}
