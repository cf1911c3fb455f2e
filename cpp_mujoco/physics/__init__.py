"""The physics backend: a MuJoCo quadrotor flying the grid MDP's actions.

``MuJoCoEnv`` is imported on first use: importing a light module of this package
(``geometry``, ``config``) must not load MuJoCo and dm_control.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from cpp_mujoco.physics.config import ControllerGains, PhysicsConfig

if TYPE_CHECKING:
    from cpp_mujoco.physics.envs.single import MuJoCoEnv

__all__ = ["ControllerGains", "MuJoCoEnv", "PhysicsConfig"]


def __getattr__(name: str):
    if name == "MuJoCoEnv":
        from cpp_mujoco.physics.envs.single import MuJoCoEnv  # heavy: MuJoCo, dm_control

        return MuJoCoEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
