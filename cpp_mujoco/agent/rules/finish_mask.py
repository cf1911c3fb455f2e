"""The finish mask: a greedy agent does not land while an unseen target is still within reach —
while some cell that shows one can be reached and left for home within the remaining budget.

Why: the paper's reward charges every move (the movement penalty) and discounts what comes
later (γ = 0.95), so covering the last few scattered targets can be worth less to the agent than
landing now; the benchmark scores coverage. Measured on 32 validation-range 16×16 maps (every 5th
budget), the general agent fell furthest behind the safe greedy planner at the largest budgets
(−3.5 points at 75, +1.5 at 30) and often landed with budget and reachable targets left. The
rule is the safe greedy planner's own test for having a goal
(:meth:`~cpp_mujoco.grid.graph.MapGraph.returnable_goals`, on the map's graph with its
obstacles where the observation has an ``obstacle`` layer: a target hidden from a cell is not
shown by it), so the agent lands where the planner would land. It only ever removes the
landing: an episode flown with it covers at least what the same episode without it covers
(coverage never falls, and where the two part the unmasked one lands), and the return mask it
is combined with still lands every calm-air episode. The distances are calm-air moves; in an
observed wind the return rule, which prices the way home at that wind, still decides which
actions are safe, and a row whose only allowed action is the landing keeps it.

Like the revisit mask it is a rule of the policy, not of training (the soft-max explores, the
DDQN target reads the Q-values); results name it (:data:`FINISH_RULE`, ``conditions.policy``).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, ClassVar

import numpy as np

from cpp_mujoco.agent.rules.base import Observation, QValues, Stateless, map_groups
from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.graph import MapGraph, graph_from_observation
from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.planners.rollout import decode_observation

# what results record of the rule (policy_identity); a changed rule gets a new name here
FINISH_RULE = (
    "finish-v1 (no landing while a cell showing an unseen target can be reached and left for "
    "home within the budget in calm-air moves, the safe greedy planner's goals, unless the "
    "landing is the only action left)"
)
_CHUNK_ELEMENTS = 1 << 21  # episodes × cells decided at once: bounds the (N, H·W) temporaries


def goal_chunks(
    obs: Observation, fov_side: int = GridConfig.fov_side, row_cells: int = 1
) -> Iterator[tuple[MapGraph, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """(graph, rows, flat positions, dist, goal) for chunks of a batch, map by map
    (:func:`~cpp_mujoco.agent.rules.base.map_groups`): each row's distances and returnable goals
    (:meth:`~cpp_mujoco.grid.graph.MapGraph.returnable_goals`), the safe greedy planner's goals
    that the finish and progress masks read. ``row_cells``: the H·W-sized temporaries a caller
    keeps per row (chunks bound them)."""
    pos, budget, coverage = decode_observation(obs)
    for part, rows in map_groups(obs):
        g = graph_from_observation(part, fov_side)
        chunk = max(1, _CHUNK_ELEMENTS // (row_cells * g.num_cells))
        for lo in range(0, rows.size, chunk):
            r = rows[lo : lo + chunk]
            _, dist, goal = g.returnable_goals(pos[r], budget[r], coverage[r])
            yield g, r, pos[r], dist, goal


def targets_in_reach(obs: dict[str, np.ndarray], fov_side: int = GridConfig.fov_side) -> np.ndarray:
    """(N,) bool for a batch of observations: some unseen target can still be seen and the way
    home paid after it — seen through the map's view, less what its obstacles hide where the
    observation has an ``obstacle`` layer. A batch whose rows carry their own maps
    ((N, 3, H, W)) is decided map by map (:func:`~cpp_mujoco.agent.rules.base.map_groups`)."""
    out = np.zeros(np.shape(obs["position"])[0], dtype=bool)
    for _, rows, _, _, goal in goal_chunks(obs, fov_side):
        out[rows] = goal.any(axis=1)
    return out


def finish_allowed(
    obs: dict[str, np.ndarray], allowed: np.ndarray, wider: np.ndarray | None = None
) -> np.ndarray:
    """``allowed`` (N, 5 bool) without the landing in the rows that still have a target in
    reach. A row so left with no action takes the moves of ``wider`` (the actions allowed before
    the revisit mask: flying back over a cell costs one unit, landing ends the coverage), and
    one left with none of those keeps ``allowed``."""
    allowed = np.asarray(allowed, dtype=bool)
    wider = allowed if wider is None else np.asarray(wider, dtype=bool)
    in_reach = targets_in_reach(obs)
    kept = allowed.copy()
    kept[in_reach, LAND] = False
    empty = ~kept.any(axis=1)
    kept[empty] = wider[empty]
    kept[empty & in_reach, LAND] = False
    empty = ~kept.any(axis=1)
    kept[empty] = allowed[empty]
    return kept


class FinishMask(Stateless):
    """No landing while an unseen target can still be reached and left for home (a soft rule;
    a row so left with no action takes the moves of ``floor``)."""

    name: ClassVar[str] = "finish-mask"
    rule: ClassVar[str] = FINISH_RULE
    hard: ClassVar[bool] = False

    def allowed(
        self, obs: Observation, allowed: np.ndarray, floor: np.ndarray, q_values: QValues
    ) -> np.ndarray:
        return finish_allowed(obs, allowed, wider=floor)

    def identity(self) -> dict[str, Any]:
        return {"finish_rule": self.rule}
