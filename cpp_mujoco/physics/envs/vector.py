"""The native batched physics env: ``gymnasium.make_vec("cpp_mujoco/MuJoCo-v0", num_envs=N)``.

N quadrotors fly their grid actions together
(:class:`~cpp_mujoco.physics.envs.episodes.FlightEpisodes` on
:class:`~cpp_mujoco.physics.flight.Flight`): one control tick for all of them
(compiled with numba), their ``MjData`` stepped in one
``mujoco.batch`` call on ``threads`` threads. Everything around the flight is the grid vector
env's (:class:`~cpp_mujoco.grid.vector_env.GridVectorEnv`): seeding
(``reset(seed=[...])``, one generator per env, drawn in a single env's order), per-env reset
options (``start``, ``budget`` as arrays, ``reset_mask``), the autoreset modes, the observation
and the MDP's rules (:meth:`GridMDP.apply`). Each env's episode is the one a single
``MuJoCo-v0`` with the same seed, options and actions flies — the same doubles
(``tests/test_physics_vector_env.py``). A macro-action takes each drone its own time; the
drones that are done wait without physics until the slowest one has finished.

Infos are the single env's keys as arrays (``crash_reason`` an object array of str / None).
``render_mode="rgb_array"`` renders the grid view of each env (zones, coverage, UAV); the 3D
chase camera is the single env's.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode

from cpp_mujoco.grid.mdp import GridConfig, StepOutcome
from cpp_mujoco.grid.vector_env import GridVectorEnv
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.envs.episodes import FlightEpisodes
from cpp_mujoco.physics.envs.single import make_configs
from cpp_mujoco.physics.parts import Controller, WindModel


class MuJoCoVectorEnv(GridVectorEnv):
    """N ``MuJoCo-v0`` episodes stepped together. Keywords as ``MuJoCo-v0`` (physics and grid
    options); ``threads``: threads stepping MuJoCo (default 1 — one per core this process may
    use is the fastest when it has the cores to itself). ``wind_directions``: one direction per
    env (degrees, as ``wind_direction``) for a batch that flies one weather from several
    directions — env i flies (and observes) what a single env with ``wind_direction`` =
    ``wind_directions[i]`` does; ``physics_config`` then records only the first.
    ``wind_model``, ``controller_model``: a user's parts for all drones
    (:mod:`~cpp_mujoco.physics.parts`)."""

    def __init__(
        self,
        num_envs: int = 1,
        map: str | os.PathLike | GridMap = "A",  # noqa: A002 - the design's keyword
        config: PhysicsConfig | None = None,
        grid_config: GridConfig | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        render_mode: str | None = None,
        threads: int = 1,
        wind_directions: Any = None,
        wind_model: WindModel | None = None,
        controller_model: Controller | None = None,
        **kwargs: Any,
    ):
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be a whole number >= 1, got {num_envs!r}")
        if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
            raise ValueError(f"threads must be a whole number >= 1, got {threads!r}")
        self.physics_config, grid = make_configs(config, grid_config, kwargs)
        super().__init__(num_envs, map, grid, autoreset_mode, render_mode)
        directions = None
        if wind_directions is not None:
            directions = np.asarray(wind_directions, dtype=float)
            if directions.shape != (num_envs,) or not np.isfinite(directions).all():
                raise ValueError(
                    f"wind_directions must be {num_envs} finite degrees, got {wind_directions!r}"
                )
        self.episodes = FlightEpisodes(
            self.grid_map, self.physics_config, grid.fov_side, self.mdp, threads, directions,
            controller=controller_model, wind=wind_model,
        )  # fmt: skip
        self.model, self.flight = self.episodes.model, self.episodes.flight
        self.unit_energy, self.guards = self.episodes.unit_energy, self.episodes.guards
        self.wind_directions = self.episodes.wind_directions

    def close(self, **kwargs: Any) -> None:
        self.flight.close()
        super().close(**kwargs)

    # ------------------------------------------------------------------ the backend's part
    def _on_reset(self, idx: np.ndarray) -> None:
        self.episodes.reset(self.mdp, idx, self.np_random)

    def _transition(self, actions: np.ndarray, active: np.ndarray) -> StepOutcome:
        return self.episodes.transition(self.mdp, actions, active)

    _NO_STATE = (
        "a physics env's state is MuJoCo's and its controllers': checkpoint the policy, "
        "not the physics episode"
    )

    def state_dict(self) -> dict[str, Any]:
        raise NotImplementedError(self._NO_STATE)

    def load_state_dict(self, state) -> None:
        raise NotImplementedError(self._NO_STATE)

    # ------------------------------------------------------------------ views
    def _infos(self) -> dict[str, np.ndarray]:
        info = self.mdp.info()
        info.update(self.episodes.infos())
        info.update({f"_{k}": self._all for k in list(info)})
        return info
