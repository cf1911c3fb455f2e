"""The paper's grid MDP: safety controller, coverage bookkeeping, batched rules, gymnasium envs."""

from cpp_mujoco.grid.mdp import GridConfig, GridMDP, Rewards, StepOutcome
from cpp_mujoco.grid.safety import ACTION_NAMES, LAND, NUM_ACTIONS, SafetyController

__all__ = [
    "ACTION_NAMES",
    "LAND",
    "NUM_ACTIONS",
    "GridConfig",
    "GridMDP",
    "Rewards",
    "SafetyController",
    "StepOutcome",
]
