"""The safe greedy planner for wind: moves cost what the observed wind makes them cost.

:class:`~cpp_mujoco.planners.safe_greedy.SafeGreedyPlanner` keeps a way home of so many unit
moves; in wind an upwind way home costs more than its move count and gusts spread it. This
planner reads the wind in the observation (``obs["wind"]``: east, north m/s — the grid wind
option's episode wind, the physics env's configured one; zeros in the paper's MDP), prices each
heading with the calibrated cost table (``grid/wind_costs.json``: mean and spread per kind at
that speed) and keeps, after every move, the expected way home plus the :class:`ReturnMargin`
(k σ of that way, widened by the gusts' correlation, a reserve, and the landing unit) — the
return guard's rule, decided from the forecast instead of the flown moves.

Each step it heads for the cell with the most new target cells per expected unit spent among
those it can reach and still return from with that margin; when none is left, or the next move
towards it would cut into the margin (gusts cost more than expected), it flies the cheapest way
home and lands. In calm air it is the safe greedy planner with costs of 0.98 instead of 1 and a
0.1-unit reserve. Used as the guide and demonstrator for wind-robust agents.
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.graph import MapGraph, graph_from_observation
from cpp_mujoco.grid.way_home import (
    HEADINGS,
    ReturnMargin,
    correlation_widening,
    cost_from,
    cost_to,
)
from cpp_mujoco.grid.wind import action_kind, wind_costs
from cpp_mujoco.planners.rollout import decode_observation

_CHUNK_ELEMENTS = 1 << 19  # episodes × cells decided at once: bounds the (N, H·W, 4) temporaries


def wind_from_observation(obs: dict[str, np.ndarray], n: int) -> tuple[np.ndarray, np.ndarray]:
    """(speed m/s, direction it blows from, degrees clockwise from north) per episode."""
    wind = np.asarray(obs.get("wind", np.zeros((n, 2))), dtype=np.float64).reshape(n, 2)
    speed = np.hypot(wind[:, 0], wind[:, 1])
    # the air moves towards (east, north) = −speed·(sin θ, cos θ) for a wind from θ
    wind_from = np.degrees(np.arctan2(-wind[:, 0], -wind[:, 1])) % 360.0
    return speed, wind_from


class WindSafeGreedyPlanner:
    name = "safe-greedy-wind"

    def __init__(self, fov_side: int = 3, margin: ReturnMargin | None = None):
        self.fov_side = fov_side
        self.margin = margin or ReturnMargin()
        self.table = wind_costs()

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        g = graph_from_observation(obs, self.fov_side)
        pos, budget, coverage = decode_observation(obs)
        speed, wind_from = wind_from_observation(obs, pos.size)
        chunk = max(1, _CHUNK_ELEMENTS // g.num_cells)
        parts = [
            self._decide(g, *(a[i : i + chunk] for a in (pos, budget, coverage, speed, wind_from)))
            for i in range(0, pos.size, chunk)
        ]
        return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)

    def heading_costs(self, speed: np.ndarray, wind_from: np.ndarray):
        """(mean (N, 4), variance (N, 4), land cost (N,), correlation widening (N,)) in units."""
        top = self.table.speeds[-1]
        mean, std, rho = self.table.at(np.minimum(speed, top))
        headings = np.arange(HEADINGS)[None, :]
        no = np.zeros((speed.size, HEADINGS), dtype=bool)
        kind = action_kind(headings, no, no, wind_from[:, None])
        rows = np.arange(speed.size)[:, None]
        land = mean[:, 4]
        return mean[rows, kind], std[rows, kind] ** 2, land, correlation_widening(rho)

    def _decide(self, g: MapGraph, pos, budget, coverage, speed, wind_from) -> np.ndarray:
        """Each episode's action; episodes are independent, so any chunking decides the same."""
        n = pos.size
        rows = np.arange(n)
        cost, var, land, widen = self.heading_costs(speed, wind_from)
        sigmas, reserve = self.margin.margin(speed)
        landing = np.broadcast_to(g.grid_map.landing.reshape(1, -1), (n, g.num_cells))
        home, home_var = cost_to(g.safety, landing, cost, var)
        # what must be left on arriving at a cell: its way home with the margin, then one unit
        # to land on (the grid's rule: a landing needs a whole unit left)
        keep = home + sigmas[:, None] * np.sqrt(home_var * widen[:, None]) + 1.0 + reserve[:, None]
        keep = np.maximum(keep, land[:, None])

        unseen = ~coverage & g.grid_map.target.reshape(-1)
        gain = g.new_targets_seen(unseen)
        spend = cost_from(g.safety, pos, cost)  # expected units from here to each cell
        reachable = (spend > 0) & (spend + keep <= budget[:, None]) & (gain > 0)
        score = np.where(reachable, gain / np.maximum(spend, 1e-9), -1.0)
        goal = score.argmax(axis=1)
        has_goal = score[rows, goal] > 0

        neighbours = g.safety.next_cell[pos, :HEADINGS]  # (N, 4)
        moves_ok = g.safety.accepted[pos, :HEADINGS]
        goal_cell = np.zeros((n, g.num_cells), dtype=bool)
        goal_cell[rows, goal] = True
        to_goal, _ = cost_to(g.safety, goal_cell, cost)
        on_way = np.isclose(cost + to_goal[rows[:, None], neighbours], to_goal[rows, pos][:, None])
        toward_goal = moves_ok & on_way
        goal_move = np.where(toward_goal, gain[rows[:, None], neighbours] + 1, 0).argmax(axis=1)
        # the move must still leave the way home paid, as far as the observed budget tells
        after = budget - cost[rows, goal_move]
        safe = after >= keep[rows, neighbours[rows, goal_move]]
        go = has_goal & toward_goal[rows, goal_move] & safe

        home_step = np.where(moves_ok, cost + home[rows[:, None], neighbours], np.inf)
        home_move = home_step.argmin(axis=1)
        on_landing = g.grid_map.landing.reshape(-1)[pos]
        return np.where(go, goal_move, np.where(on_landing, LAND, home_move))
