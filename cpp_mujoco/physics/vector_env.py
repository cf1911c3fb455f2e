"""The native batched physics env: ``gymnasium.make_vec("cpp_mujoco/MuJoCo-v0", num_envs=N)``.

N quadrotors fly their grid actions together
(:class:`~cpp_mujoco.physics.batched_flight.BatchedFlight`): one control tick for all of them
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

from cpp_mujoco.grid.mdp import GridConfig, Outcome, StepOutcome
from cpp_mujoco.grid.vector_env import GridVectorEnv
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.batched_flight import HOVER, LAND, MOVE, BatchedFlight
from cpp_mujoco.physics.calibration import unit_energy
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.env import BUDGET_EXHAUSTED, make_configs
from cpp_mujoco.physics.return_guard import ReturnGuard


class MuJoCoVectorEnv(GridVectorEnv):
    """N ``MuJoCo-v0`` episodes stepped together. Keywords as ``MuJoCo-v0`` (physics and grid
    options); ``threads``: threads stepping MuJoCo (default 1 — one per core this process may
    use is the fastest when it has the cores to itself). ``wind_directions``: one direction per
    env (degrees, as ``wind_direction``) for a batch that flies one weather from several
    directions — env i flies (and observes) what a single env with ``wind_direction`` =
    ``wind_directions[i]`` does; ``physics_config`` then records only the first."""

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
        **kwargs: Any,
    ):
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be a whole number >= 1, got {num_envs!r}")
        if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
            raise ValueError(f"threads must be a whole number >= 1, got {threads!r}")
        self.physics_config, grid = make_configs(config, grid_config, kwargs)
        super().__init__(num_envs, map, grid, autoreset_mode, render_mode)
        c = self.physics_config
        self.model = compile_arena(build_arena(self.grid_map, c, grid.fov_side))
        self.flight = BatchedFlight(
            self.model, self.grid_map, c, num_envs, self.mdp.coverage, threads
        )
        self.unit_energy = unit_energy(c)
        drag = self.flight.one.drag.half_rho_cda
        self.guards = (
            [ReturnGuard(self.grid_map, self.unit_energy, drag) for _ in range(num_envs)]
            if c.return_guard
            else None
        )
        self.wind_directions = np.full(num_envs, float(c.wind_direction))
        if wind_directions is not None:
            given = np.asarray(wind_directions, dtype=float)
            if given.shape != (num_envs,) or not np.isfinite(given).all():
                raise ValueError(
                    f"wind_directions must be {num_envs} finite degrees, got {wind_directions!r}"
                )
            for i in np.flatnonzero(given != self.wind_directions).tolist():
                self.flight.set_wind_direction(i, given[i])
            self.wind_directions = given
        self._guard_active = np.zeros(num_envs, dtype=bool)
        self._tracking = np.zeros(num_envs)
        self._crash_reason = np.full(num_envs, None, dtype=object)

    def close(self, **kwargs: Any) -> None:
        self.flight.close()
        super().close(**kwargs)

    # ------------------------------------------------------------------ the backend's part
    def _on_reset(self, idx: np.ndarray) -> None:
        m, c, rngs = self.mdp, self.physics_config, self.np_random
        for i in idx.tolist():
            row, col = divmod(int(m.position[i]), m.width)
            self.flight.reset(i, row, col, float(m.budget[i]) * self.unit_energy, rngs[i])
            m.winds.set(i, c.wind_speed, self.wind_directions[i])  # observed, as a single env
            if self.guards is not None:
                self.guards[i].reset()
        self._guard_active[idx] = False
        self._tracking[idx] = 0.0
        self._crash_reason[idx] = None

    def _remaining(self) -> np.ndarray:
        f = self.flight
        return np.maximum(f.capacity - f.energy_used, 0.0)

    def _transition(self, actions: np.ndarray, active: np.ndarray) -> StepOutcome:
        """Safety decision (and the return guard), then the flight of every active env; its
        outcome goes through the grid's rules, exactly as :meth:`MuJoCoEnv._transition`."""
        m, f = self.mdp, self.flight
        cells = m.position
        actions = actions.copy()
        if self.guards is not None:
            remaining = self._remaining()
            for i in np.flatnonzero(active).tolist():
                guard = self.guards[i]
                actions[i] = guard.filter(int(cells[i]), int(actions[i]), float(remaining[i]))
                self._guard_active[i] = guard.active
        next_cell, rejected, lands = m.safety.decide(cells, actions)
        kinds = np.where(lands, LAND, np.where(rejected, HOVER, MOVE))
        result = f.fly(kinds, np.where(lands | rejected, cells, next_cell), active)
        if self.guards is not None:
            for i in np.flatnonzero(active).tolist():
                self.guards[i].observe(
                    int(actions[i]), bool(rejected[i]), float(result["energy"][i]),
                    tuple(f.controller.disturbance[i]),
                )  # fmt: skip
        budget = np.floor(self._remaining() / self.unit_energy + 1e-9).astype(m.budget.dtype)
        failed = result["failure"] != None  # noqa: E711 - elementwise over an object array
        out = m.apply(
            Outcome(
                next_cell=np.where(active, next_cell, cells),
                rejected=rejected & active,
                landed=result["landed"],
                spent=np.where(active, m.budget - budget, 0).astype(m.budget.dtype),
                newly_seen=result["newly_seen"],
                failed=failed,
            ),
            active,
        )
        self._tracking = np.where(active, result["tracking_error"], self._tracking)
        for i in np.flatnonzero(active).tolist():
            reason = result["failure"][i]
            self._crash_reason[i] = reason or (BUDGET_EXHAUSTED if out.crashed[i] else None)
        return out

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
        f = self.flight
        info = self.mdp.info()
        info.update(
            energy_used_j=f.energy_used.copy(),
            flight_time_s=f.state[:, 0].copy(),
            nfz_violations=f.nfz_violations.copy(),
            max_track_error_m=f.max_track_error.copy(),
            tracking_error_m=self._tracking.copy(),
            state_of_charge=f.battery.soc.copy(),
            battery_voltage_v=f.battery.voltage(),
            crash_reason=self._crash_reason.copy(),
            guard_active=self._guard_active.copy(),
            guard_takeovers=np.array(
                [g.takeovers for g in self.guards] if self.guards else [0] * self.num_envs
            ),
        )
        info.update({f"_{k}": self._all for k in list(info)})
        return info
