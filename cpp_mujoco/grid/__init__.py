"""The paper's grid MDP: actions, safety controller, coverage bookkeeping, batched rules, envs."""

from cpp_mujoco.grid.actions import ACTION_NAMES, LAND, NUM_ACTIONS
from cpp_mujoco.grid.mdp import GridConfig, GridMDP, Rewards, StepOutcome
from cpp_mujoco.grid.safety import SafetyController

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
