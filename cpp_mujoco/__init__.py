"""cpp_mujoco: UAV coverage path planning under power constraints, on a grid and in MuJoCo."""

import os

from gymnasium.envs.registration import register, registry

from cpp_mujoco.review.rendering import default_gl_backend

# MuJoCo picks its GL backend once, at import: give it a headless one unless the user chose.
os.environ.setdefault("MUJOCO_GL", default_gl_backend())

__version__ = "0.1.0"

if "cpp_mujoco/Grid-v0" not in registry:
    register(
        id="cpp_mujoco/Grid-v0",
        entry_point="cpp_mujoco.grid.env:GridEnv",
        vector_entry_point="cpp_mujoco.grid.vector_env:GridVectorEnv",
    )

if "cpp_mujoco/MuJoCo-v0" not in registry:
    register(id="cpp_mujoco/MuJoCo-v0", entry_point="cpp_mujoco.physics.env:MuJoCoEnv")
