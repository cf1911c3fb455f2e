"""The return rule: which actions keep the way home paid, in calm air and in an observed wind.

In calm air every action costs one unit, so action a is paid iff the budget left after it covers
the actions still needed to be landed (:attr:`MapGraph.home_after
<cpp_mujoco.grid.graph.MapGraph.home_after>`, ``after``): ``after <= budget − 1`` — the safe
greedy planner's invariant as an action set, the general agent's return mask.

In wind a move costs what its heading and the gusts make it cost (:mod:`~cpp_mujoco.grid.wind`).
The mask must stay a table lookup (it runs on every replay minibatch), so instead of the wind
planners' per-episode Bellman–Ford over heading costs it bounds the way home: every move of it is
priced at the dearest moving kind's mean at the observed wind speed (at least one unit), its spread
at the widest kind's, widened by the gusts' correlation, with the wind planners' margin
(:class:`~cpp_mujoco.grid.way_home.ReturnMargin`) on top — the return guard's rule with the
heading-blind bound. A move is paid iff ``budget ≥ u·after + 1 + k·σ·√after + reserve`` (u units a
move, the whole unit a landing needs); a landing iff a unit is left. At 0 m/s this is the calm
rule exactly (u = 1, no margin): a calm episode of the wind option costs 0.98 a move, so the calm
rule is conservative there. When gusts have eaten the margin and nothing is paid, the way home is
allowed: the accepted actions with the fewest actions still needed.
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.way_home import ReturnMargin, correlation_widening
from cpp_mujoco.grid.wind import KIND_INDEX, wind_costs

# what results record of the return mask's rule (policy_identity): the same agent file flies
# differently under another rule, so a changed rule gets a new name here
RETURN_RULE = (
    "safe-actions-v3 (accepted actions whose way home is paid: in calm air v2's unit costs; in an "
    "observed wind each move at the dearest kind's mean + the wind planners' margin)"
)
MOVE_KINDS = [KIND_INDEX[k] for k in ("upwind", "downwind", "crosswind")]
# MapGraph.home_after of a rejected action: more than any budget, so the rule never pays it
REJECTED_AFTER = 1 << 30


def wind_allowance(
    wind: np.ndarray, margin: ReturnMargin | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row of observed winds (N, 2) (east, north m/s): (units a move (N,), standard
    deviation a move × the margin's sigmas (N,), reserve units (N,)); (1, 0, 0) in calm air."""
    wind = np.asarray(wind, dtype=np.float64).reshape(-1, 2)
    speed = np.hypot(wind[:, 0], wind[:, 1])
    table = wind_costs()
    mean, std, rho = table.at(np.minimum(speed, table.speeds[-1]))
    sigmas, reserve = (margin or ReturnMargin()).margin(speed)
    windy = speed > 0
    units = np.where(windy, np.maximum(mean[:, MOVE_KINDS].max(axis=1), 1.0), 1.0)
    spread = std[:, MOVE_KINDS].max(axis=1) * np.sqrt(correlation_widening(rho)) * sigmas
    return units, np.where(windy, spread, 0.0), np.where(windy, reserve, 0.0)


def paid_actions(
    after: np.ndarray,
    budget: np.ndarray,
    wind: np.ndarray | None = None,
    margin: ReturnMargin | None = None,
) -> np.ndarray:
    """(N, 5) bool: the actions the rule allows. ``after`` (N, 5): actions still needed to be
    landed after each action (0 for a landing, :data:`REJECTED_AFTER`
    for a rejected one); ``budget`` (N,) or (N, 1): the (observed) budget; ``wind`` (N, 2) the
    observed wind (None or zeros: calm air); ``margin``: the wind planners'."""
    after = np.asarray(after)
    n = after.shape[0]
    budget = np.asarray(budget, dtype=np.float64).reshape(n, 1)
    if wind is None or not np.any(wind):
        return after <= budget - 1
    units, spread, reserve = (a[:, None] for a in wind_allowance(wind, margin))
    moves = after.astype(np.float64)
    needed = units * moves + 1.0 + spread * np.sqrt(moves) + reserve
    paid = np.where(after == 0, budget >= 1.0, budget >= needed)
    stuck = ~paid.any(axis=1)
    if stuck.any():  # the margin is spent: the way home (rejected actions stay out)
        home = after[stuck] == after[stuck].min(axis=1, keepdims=True)
        paid[stuck] = home & (after[stuck] < REJECTED_AFTER)
    return paid
