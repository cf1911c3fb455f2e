"""cpp_mujoco: UAV coverage path planning under power constraints, on a grid and in MuJoCo.

Importing it only registers the gymnasium envs: no environment variables, no MuJoCo, no GL.
The offscreen GL backend is chosen when something first renders
(:func:`cpp_mujoco.physics.view.rendering.select_gl`).
"""

from gymnasium.envs.registration import register, registry

__version__ = "0.1.0"

if "cpp_mujoco/Grid-v0" not in registry:
    register(
        id="cpp_mujoco/Grid-v0",
        entry_point="cpp_mujoco.grid.env:GridEnv",
        vector_entry_point="cpp_mujoco.grid.vector_env:GridVectorEnv",
    )

if "cpp_mujoco/MuJoCo-v0" not in registry:
    register(
        id="cpp_mujoco/MuJoCo-v0",
        entry_point="cpp_mujoco.physics.envs.single:MuJoCoEnv",
        vector_entry_point="cpp_mujoco.physics.envs.vector:MuJoCoVectorEnv",
    )
