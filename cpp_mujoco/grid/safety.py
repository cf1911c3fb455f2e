"""The safety controller (paper §II): it accepts or rejects each proposed action.

It is the single implementation of the acceptance rule, used by the grid MDP and by the physics
backend alike. Everything is precomputed as a lookup table over (cell, action), so deciding for a
whole batch is one gather.
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.actions import LAND, MOVES
from cpp_mujoco.maps import GridMap


class SafetyController:
    """Lookup tables over flat cell index ``p = row * W + col`` and action ``a``.

    ``next_cell[p, a]``: the cell after the action if accepted, else ``p`` (the UAV hovers).
    ``accepted[p, a]``: moves stay on the grid and off no-fly cells; ``land`` needs a landing cell.
    ``lands[p, a]``: the action is an accepted ``land``.
    """

    def __init__(self, grid_map: GridMap):
        h, w = grid_map.shape
        rows, cols = np.divmod(np.arange(h * w), w)
        dest_r = rows[:, None] + MOVES[None, :, 0]
        dest_c = cols[:, None] + MOVES[None, :, 1]
        inside = (dest_r >= 0) & (dest_r < h) & (dest_c >= 0) & (dest_c < w)
        dest = np.where(inside, dest_r * w + dest_c, 0)
        accepted = inside & ~grid_map.nfz.reshape(-1)[dest]
        accepted[:, LAND] = grid_map.landing.reshape(-1)
        self.accepted = accepted
        self.rejected = ~accepted
        self.next_cell = np.where(accepted, dest, np.arange(h * w)[:, None])
        self.lands = np.zeros_like(accepted)
        self.lands[:, LAND] = accepted[:, LAND]
        self.width = w

    def decide(self, cell, action) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(next cell, rejected, lands) for arrays (or scalars) of flat cells and actions."""
        return self.next_cell[cell, action], self.rejected[cell, action], self.lands[cell, action]
