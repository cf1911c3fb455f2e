"""A safe greedy planner: it lands every time and covers what it can on the way.

Invariant: the remaining budget never drops below ``home[position]`` (the actions needed to be
landed), so a way back always exists. Each step it heads for the cell with the most new target
cells per move among those it can reach *and* still return from; when there is none it flies home
along a shortest path and lands. Everything is batched: one call decides for N episodes.
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.graph import MapGraph, graph_from_observation
from cpp_mujoco.planners.rollout import decode_observation

_CHUNK_ELEMENTS = 1 << 21  # episodes × cells decided at once: bounds the (N, H·W) temporaries


class SafeGreedyPlanner:
    name = "safe-greedy"

    def __init__(self, fov_side: int = 3):
        self.fov_side = fov_side

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        g = graph_from_observation(obs, self.fov_side)
        pos, budget, coverage = decode_observation(obs)
        chunk = max(1, _CHUNK_ELEMENTS // g.num_cells)
        if pos.size <= chunk:
            return self._decide(g, pos, budget, coverage)
        return np.concatenate(
            [
                self._decide(g, pos[i : i + chunk], budget[i : i + chunk], coverage[i : i + chunk])
                for i in range(0, pos.size, chunk)
            ]
        )

    @staticmethod
    def _decide(g: MapGraph, pos, budget, coverage) -> np.ndarray:
        """Each episode's action; episodes are independent, so any chunking decides the same."""
        rows = np.arange(pos.size)
        gain, dist, reachable = g.returnable_goals(pos, budget, coverage)
        score = np.where(reachable, gain / np.maximum(dist, 1), -1.0)
        goal = score.argmax(axis=1)
        has_goal = score[rows, goal] > 0

        neighbours = g.safety.next_cell[pos, :LAND]
        moves_ok = g.safety.accepted[pos, :LAND]
        # d(neighbour, goal) = d(goal, neighbour): neither is no-fly where has_goal (MapGraph)
        toward_goal = moves_ok & (
            g.distance_between(goal, neighbours) == dist[rows, goal][:, None] - 1
        )
        goal_move = np.where(toward_goal, gain[rows[:, None], neighbours] + 1, 0).argmax(axis=1)
        toward_home = moves_ok & (g.home[neighbours] == g.home[pos][:, None] - 1)
        home_move = toward_home.argmax(axis=1)
        on_landing = g.grid_map.landing.reshape(-1)[pos]
        return np.where(has_goal, goal_move, np.where(on_landing, LAND, home_move))
