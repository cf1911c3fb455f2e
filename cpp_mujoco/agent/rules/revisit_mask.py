"""The revisit mask: a greedy agent does not fly back into a cell it has flown through since its
coverage last grew, unless that cell shows it an unseen target or nothing else is allowed.

Why: a deterministic greedy policy in a state that differs from an earlier one only by the
budget takes the same action again, so a two-cell back-and-forth, once begun, runs until the way
home calls it back — the general agent's largest coverage losses on unseen maps are such cycles
near its start (``scripts/agent_loops.py``). The state (cell, coverage) of such a move was already
reached with more budget left, and a move costs budget, so the cycle gained nothing and spent
budget. The mask keeps what the policy's Q-values rank, minus those moves: the argmax then takes
the best action that goes somewhere new. It is no pruning proven to keep the optimum (from a dead
end the best way on may lead back), which is why the policy falls back to every allowed action
when the mask leaves no move and no landing. A cell's view is the grid's: on a map with obstacles
(an observation with an ``obstacle`` layer) the square less what they hide
(:meth:`~cpp_mujoco.grid.graph.MapGraph.new_targets_seen`, map by map).

It needs the episode's memory — the cells flown since the coverage last grew — so the agent
holds one row per episode of its batch, started afresh by ``reset`` at every episode start
(:func:`cpp_mujoco.protocol.policy.start_episodes`). Training never uses it (the soft-max explores,
and the
DDQN target reads stored states without a past); validation and every result of an agent flown
with it do, and results name it (:data:`REVISIT_RULE`, ``conditions.policy``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from cpp_mujoco.agent.network import NFZ_CHANNEL, TARGET_CHANNEL
from cpp_mujoco.agent.rules.base import Observation, QValues, map_groups
from cpp_mujoco.grid.actions import LAND, MOVES
from cpp_mujoco.grid.coverage import square_fov_counts
from cpp_mujoco.grid.graph import graph_from_observation
from cpp_mujoco.grid.mdp import GridConfig

# what results record of the rule (policy_identity); a changed rule gets a new name here
REVISIT_RULE = (
    "revisit-v1 (no move into a cell flown through since the coverage last grew whose view holds "
    "no unseen target, unless no move or landing is left)"
)


class RevisitMemory:
    """The cells each episode of a batch has flown through since its coverage last grew."""

    def __init__(self, fov_side: int = GridConfig.fov_side):
        self.fov_side = fov_side
        self.visited: np.ndarray | None = None  # (N, H·W) bool
        self.covered: np.ndarray | None = None  # (N,) covered cells at the last step
        self.budget: np.ndarray | None = None  # (N,) budget at the last step

    def reset(self) -> None:
        """A new batch of episodes starts: forget every cell."""
        self.visited = self.covered = self.budget = None

    def allowed(self, obs: dict[str, np.ndarray], allowed: np.ndarray) -> np.ndarray:
        """``allowed`` (N, 5 bool: the actions the policy may take now) without the moves back
        into a fruitless cell already flown through; rows the mask would leave with no action
        keep ``allowed``. Records the observation's cells: call once per step."""
        coverage = np.asarray(obs["coverage"])
        n, h, w = coverage.shape
        cells = h * w
        position = np.asarray(obs["position"]).reshape(n, cells).argmax(axis=1)
        covered = coverage.reshape(n, cells).sum(axis=1)
        budget = np.asarray(obs["budget"], dtype=np.float64).reshape(n)
        if self.visited is None or self.visited.shape != (n, cells):
            self.visited = np.zeros((n, cells), dtype=bool)
            self.covered, self.budget = covered, budget
        # new targets seen: a new state of coverage; and a row whose budget rose or coverage
        # fell is a new episode a caller started without reset (both only fall, resp. grow)
        self.visited[(covered != self.covered) | (budget > self.budget)] = False
        self.covered, self.budget = covered, budget
        rows = np.arange(n)
        self.visited[rows, position] = True
        layers = np.asarray(obs["map"])
        if layers.ndim == 3:  # one map shared by the batch
            layers = np.broadcast_to(layers, (n, *layers.shape))
        unseen = ((layers[:, TARGET_CHANNEL] > 0) & (coverage <= 0)).reshape(n, cells)
        shows_new = self._shows_new(obs, unseen, (h, w))
        nfz = layers[:, NFZ_CHANNEL].reshape(n, cells) > 0
        row, col = np.divmod(position, w)
        back = np.zeros_like(allowed, dtype=bool)
        for action in range(LAND):
            r, c = row + MOVES[action, 0], col + MOVES[action, 1]
            inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
            cell = np.where(inside, r * w + c, position)
            cell = np.where(nfz[rows, cell], position, cell)  # the safety controller hovers
            back[:, action] = self.visited[rows, cell] & ~shows_new[rows, cell]
        kept = allowed & ~back
        empty = ~kept.any(axis=1)
        kept[empty] = allowed[empty]
        return kept

    def _shows_new(
        self, obs: Observation, unseen: np.ndarray, shape: tuple[int, int]
    ) -> np.ndarray:
        """(N, H·W) bool: the cells whose view holds an ``unseen`` target: the square, or where
        the observation has obstacles its map's view less what they hide (map by map)."""
        if not np.any(obs.get("obstacle", False)):
            return square_fov_counts(unseen, shape, self.fov_side) > 0
        shows = np.zeros_like(unseen)
        for part, rows in map_groups(obs):
            graph = graph_from_observation(part, self.fov_side)
            shows[rows] = graph.new_targets_seen(unseen[rows]) > 0
        return shows


class RevisitMask:
    """No move back into a fruitless cell flown through since the coverage last grew (a soft
    rule with a memory per episode of the batch)."""

    name: ClassVar[str] = "revisit-mask"
    rule: ClassVar[str] = REVISIT_RULE
    hard: ClassVar[bool] = False

    def __init__(self) -> None:
        self.memory = RevisitMemory()

    def reset(self, num_episodes: int) -> None:
        self.memory.reset()

    def allowed(
        self, obs: Observation, allowed: np.ndarray, floor: np.ndarray, q_values: QValues
    ) -> np.ndarray:
        return self.memory.allowed(obs, allowed)

    def identity(self) -> dict[str, Any]:
        return {"revisit_rule": self.rule}
