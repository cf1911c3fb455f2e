"""The physics backend: a MuJoCo quadrotor flying the grid MDP's actions (DESIGN §5)."""

from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.env import MuJoCoEnv

__all__ = ["MuJoCoEnv", "PhysicsConfig"]
