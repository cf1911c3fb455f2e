"""The grid MDP's five actions: their numbers, names and moves.

Everything that speaks actions — the safety controller, the spaces, the Q-network's output
layer, the planners, the recordings — reads them here, so an action's number means one thing.
"""

from __future__ import annotations

import numpy as np

NORTH, EAST, SOUTH, WEST, LAND = range(5)
ACTION_NAMES = ("north", "east", "south", "west", "land")
NUM_ACTIONS = len(ACTION_NAMES)
# (d_row, d_col) of each action; LAND does not move.
MOVES = np.array([[-1, 0], [0, 1], [1, 0], [0, -1], [0, 0]], dtype=np.int64)
