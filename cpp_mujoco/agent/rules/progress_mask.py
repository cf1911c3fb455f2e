"""The progress mask: while some unseen target can still be reached and left for home, a greedy
agent only takes moves that bring it one step nearer to a cell that shows one.

Why: on city maps the general agent's worst losses are pockets — landing pads walled by
buildings, targets it sees behind a no-fly strip. The network steers toward them, every way out
leads through cells already flown, and it wanders the pocket until the way home calls it back
(city32-s1200022: 13 % coverage where the safe greedy planner covers 44 %). The revisit mask
forbids the cells flown since the coverage last grew, but each step out shows a target or two,
the memory starts afresh, and the agent turns back in.

The rule prunes only moves that cannot matter: let the goals be the cells that show an unseen
target and can be reached and left for home within the budget (the safe greedy planner's goals,
:meth:`~cpp_mujoco.grid.graph.MapGraph.returnable_goals`). A move into a cell n that is no nearer
than the UAV's cell p to any goal is dominated: any mission continuing from n either lands
without seeing a new target (p can too, its way home is paid) or first sees one from some goal
g, at least ``d(n, g) >= d(p, g)`` moves on, where p arrives by a shortest path with as much
budget left and at least as much seen. So the mask never removes the optimum's move, unlike the
revisit mask. A rejected move (the safety controller hovers) stays where it is, nearer nothing:
pruned too. Rows without a goal are left alone (the agent flies home under the return rule).

Placed after the revisit and finish masks: a row they leave with only pruned moves takes the
moves of ``floor`` (the return rule's set) that make progress — the way out of a dead end —
and a row with none keeps ``allowed``. A rule of the policy, not of training; results name it
(:data:`PROGRESS_RULE`, ``conditions.policy``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from cpp_mujoco.agent.rules.base import Observation, QValues, Stateless
from cpp_mujoco.agent.rules.finish_mask import goal_chunks
from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.mdp import GridConfig

# what results record of the rule (policy_identity); a changed rule gets a new name here
PROGRESS_RULE = (
    "progress-v1 (while a cell showing an unseen target can be reached and left for home in "
    "calm-air moves, only the moves one step nearer to some such cell; a row left with none "
    "takes those of the return rule's actions, else keeps its actions)"
)


def progress_moves(obs: Observation, fov_side: int = GridConfig.fov_side) -> np.ndarray:
    """(N, 5) bool for a batch of observations: the moves that end one step nearer to some
    returnable goal (every action in a row without a goal; the landing always)."""
    out = np.ones((np.shape(obs["position"])[0], LAND + 1), dtype=bool)
    for g, rows, pos, dist, goal in goal_chunks(obs, fov_side, row_cells=LAND):
        after = g.safety.next_cell[pos, :LAND]  # (k, 4): a rejected move stays put
        dist_after = g.distance_from(after.ravel()).reshape(rows.size, LAND, -1)
        nearer = (goal[:, None, :] & (dist_after < dist[:, None, :])).any(axis=2)
        out[rows, :LAND] = np.where(goal.any(axis=1)[:, None], nearer, True)
    return out


def progress_allowed(obs: Observation, allowed: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """``allowed`` (N, 5 bool) less the moves that bring no goal nearer; a row so left with no
    action takes the progress moves of ``floor`` (its moves only: a row with a goal does not
    land), and one with none of those keeps ``allowed``."""
    allowed = np.asarray(allowed, dtype=bool)
    progress = progress_moves(obs)
    kept = allowed & progress
    empty = ~kept.any(axis=1)
    way_out = np.asarray(floor, dtype=bool) & progress
    way_out[:, LAND] = False
    kept[empty] = way_out[empty]
    empty = ~kept.any(axis=1)
    kept[empty] = allowed[empty]
    return kept


class ProgressMask(Stateless):
    """Only moves one step nearer to a cell that shows an unseen target, while one is in reach
    (a soft rule; a row so left with no action takes the progress moves of ``floor``)."""

    name: ClassVar[str] = "progress-mask"
    rule: ClassVar[str] = PROGRESS_RULE
    hard: ClassVar[bool] = False

    def allowed(
        self, obs: Observation, allowed: np.ndarray, floor: np.ndarray, q_values: QValues
    ) -> np.ndarray:
        return progress_allowed(obs, allowed, floor)

    def identity(self) -> dict[str, Any]:
        return {"progress_rule": self.rule}
