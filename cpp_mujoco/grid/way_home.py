"""Energy to get somewhere when moves cost what the wind makes them cost, and how much to keep.

In calm air every move costs one unit and the way home is a count of moves (``MapGraph.home``).
In wind a move's cost depends on its heading (upwind, downwind, across) and gusts spread it, so
"can I still get home?" needs, per episode, the expected cost of the cheapest way and its
variance — and a margin on top. Both the wind-aware planner (batched, from the observed wind)
and the physics return guard (one flight, from its own measured moves) answer it with the rules
here: the margin is :class:`ReturnMargin`, the variance of a way adds its moves' variances,
widened by the gusts' lag-1 correlation ρ (a sum of n AR(1) terms has at most (1+ρ)/(1−ρ) times
the variance of n independent ones).

:func:`cost_to` is a batched Bellman–Ford over the safety controller's accepted moves: N episodes,
each with its own four heading costs, relaxed together in numpy until nothing changes (at most
the longest shortest path's number of moves, a few dozen on the paper's maps).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.safety import SafetyController

HEADINGS = LAND  # the four moves (N, E, S, W) are actions 0..3
OPPOSITE = np.array([2, 3, 0, 1])  # the heading that undoes each move


@dataclass(frozen=True)
class ReturnMargin:
    """How much beyond the expected way home is kept (defaults measured: docs/physics.md, "The
    return guard"): standard deviations of the way's spread and units beyond it and the landing
    unit, in calm air and from ``gusty_wind`` m/s of wind up (linear between).

    Measured with the return guard: 3σ + 0.1 everywhere left 3 crashes in 616 rated-wind
    episodes (single upwind moves in a long Dryden gust cost up to 4.9 units, a tail no Gaussian
    margin of the calibrated spread covers); 4σ + 0.3 everywhere lands them all but costs up to
    0.95 points of coverage in calm air, where 3σ + 0.1 costs ≤ 0.12.
    """

    sigmas: float = 3.0
    reserve_units: float = 0.1
    gusty_sigmas: float = 4.0
    gusty_reserve_units: float = 0.3
    gusty_wind: float = 6.0  # m/s: turbulence grows with the wind (MIL-F-8785C: σ ∝ W20)

    def margin(self, wind_speed):
        """(standard deviations, reserve units) at ``wind_speed`` m/s (scalar or array)."""
        if self.gusty_wind > 0:
            k = np.clip(np.asarray(wind_speed, dtype=np.float64) / self.gusty_wind, 0.0, 1.0)
        else:
            k = np.ones_like(np.asarray(wind_speed, dtype=np.float64))
        sigmas = self.sigmas + k * (self.gusty_sigmas - self.sigmas)
        reserve = self.reserve_units + k * (self.gusty_reserve_units - self.reserve_units)
        if np.ndim(wind_speed) == 0:
            return float(sigmas), float(reserve)
        return sigmas, reserve


def correlation_widening(rho) -> np.ndarray:
    """(1+ρ)/(1−ρ): the most a sum of AR(1) costs' variance exceeds independent ones'."""
    rho = np.asarray(rho, dtype=np.float64)
    return (1.0 + rho) / (1.0 - rho)


def cost_to(
    safety: SafetyController,
    goals: np.ndarray,
    move_cost: np.ndarray,
    move_var: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Cheapest expected cost from every cell to the nearest goal cell, per episode.

    ``goals``: (N, H·W) bool; ``move_cost``/``move_var``: (N, 4) mean and variance of one move
    in each heading. Returns (cost (N, H·W), variance of that way (N, H·W)); ``inf`` cost where
    no goal is reachable (variance 0 there). Equally cheap ways: the first heading's (N, E, S, W).
    """
    goals = np.asarray(goals, dtype=bool)
    n, cells = goals.shape
    move_cost = np.asarray(move_cost, dtype=np.float64).reshape(n, HEADINGS)
    move_var = (
        np.zeros_like(move_cost)
        if move_var is None
        else np.asarray(move_var, np.float64).reshape(n, HEADINGS)
    )
    nxt = safety.next_cell[:, :HEADINGS]  # (C, 4)
    step_cost = move_cost[:, None, :] + np.where(safety.accepted[:, :HEADINGS], 0.0, np.inf)
    rows, cols = np.arange(n)[:, None], np.arange(cells)[None, :]
    cost = np.where(goals, 0.0, np.inf)
    var = np.zeros((n, cells))
    for _ in range(2 * cells + 2):  # the costs settle first, then the variances along them
        via = cost[:, nxt] + step_cost  # (N, C, 4)
        best = via.argmin(axis=2)
        new_cost = np.where(goals, 0.0, np.take_along_axis(via, best[..., None], 2)[..., 0])
        new_var = np.where(goals, 0.0, move_var[rows, best] + var[rows, nxt[cols, best]])
        new_var[~np.isfinite(new_cost)] = 0.0
        if np.array_equal(new_cost, cost) and np.array_equal(new_var, var):
            break
        cost, var = new_cost, new_var
    return cost, var


def cost_from(safety: SafetyController, start: np.ndarray, move_cost: np.ndarray) -> np.ndarray:
    """(N, H·W) cheapest expected cost from each episode's ``start`` cell to every cell: the
    moves between non-no-fly cells are symmetric, so it is :func:`cost_to` the start with each
    heading charged as its opposite."""
    start = np.asarray(start).reshape(-1)
    goals = np.zeros((start.size, safety.next_cell.shape[0]), dtype=bool)
    goals[np.arange(start.size), start] = True
    return cost_to(safety, goals, np.asarray(move_cost)[:, OPPOSITE])[0]
