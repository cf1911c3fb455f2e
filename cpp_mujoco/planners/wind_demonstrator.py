"""The demonstrator for wind-robust agents: the beam search where the air is calm, the
wind-aware safe greedy planner where it blows.

In calm air a move costs what the beam search assumes (at most one unit: 0.98 in the grid wind
option and in MuJoCo), so its plans land and cover the most; in wind its unit costs would run
the pack flat on an upwind way home, so those episodes are planned by
:class:`~cpp_mujoco.planners.safe_greedy_wind.WindSafeGreedyPlanner`. A wind-robust agent that
learns from these keeps the paper agents' calm-air tours and learns a wind margin.
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.way_home import ReturnMargin
from cpp_mujoco.planners.beam_search import BeamSearchPlanner
from cpp_mujoco.planners.safe_greedy_wind import WindSafeGreedyPlanner, wind_from_observation


class WindDemonstrator:
    name = "beam-search-wind"

    def __init__(self, fov_side: int = 3, margin: ReturnMargin | None = None):
        self.calm = BeamSearchPlanner(fov_side=fov_side)
        self.windy = WindSafeGreedyPlanner(fov_side=fov_side, margin=margin)

    def reset(self, num_episodes: int, seed: int | None = None) -> None:
        self.calm.reset(num_episodes, seed)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        n = np.asarray(obs["position"]).shape[0]
        calm = wind_from_observation(obs, n)[0] == 0.0
        if calm.all():
            return self.calm.act(obs)
        if not calm.any():
            return self.windy.act(obs)
        actions = np.empty(n, dtype=np.int64)
        # the beam search keeps plans per row: it sees the same calm rows each step of a batch
        # (and replans any row whose state departs from its plan)
        actions[calm] = self.calm.act({k: np.asarray(v)[calm] for k, v in obs.items()})
        actions[~calm] = self.windy.act({k: np.asarray(v)[~calm] for k, v in obs.items()})
        return actions
