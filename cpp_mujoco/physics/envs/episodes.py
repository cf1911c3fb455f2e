"""What turns the grid MDP's actions into flights, for the single and the vector ``MuJoCo-v0``:
the one physics backend of both envs, over a batch of drones.

The env (single or vector) owns the :class:`~cpp_mujoco.grid.mdp.GridMDP` and its rules; this
owns the drones: each reset puts a drone over its start with a pack of the episode's budget,
each step flies the safety controller's decision (the return guard's, where it is on) through
:class:`~cpp_mujoco.physics.flight.Flight` and hands the outcome to
:meth:`GridMDP.apply`. ``MuJoCo-v0`` is a batch of one of it, ``make_vec`` a batch of N, as
``Grid-v0`` is a batch of one ``GridMDP``.
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.mdp import GridMDP, Outcome, StepOutcome
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.action import HOVER, LAND, MOVE
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.calibration import unit_energy
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.flight import Flight
from cpp_mujoco.physics.parts import Controller, WindModel
from cpp_mujoco.physics.return_guard import ReturnGuard

BUDGET_EXHAUSTED = "budget exhausted before landing"


class FlightEpisodes:
    """``n`` drones over ``grid_map`` flying the episodes of ``mdp`` (its coverage rows are the
    ones the cameras mark). ``threads``: threads stepping MuJoCo; ``wind_directions``: per drone,
    the direction its steady wind blows from (degrees; None: ``config.wind_direction``);
    ``controller``, ``wind``: a user's parts (:mod:`~cpp_mujoco.physics.parts`, None: the
    built-in ones)."""

    def __init__(
        self,
        grid_map: GridMap,
        config: PhysicsConfig,
        fov_side: int,
        mdp: GridMDP,
        threads: int = 1,
        wind_directions: np.ndarray | None = None,
        controller: Controller | None = None,
        wind: WindModel | None = None,
    ):
        n = mdp.num_envs
        self.config = config
        for name, part, protocol in (("controller_model", controller, Controller),
                                     ("wind_model", wind, WindModel)):  # fmt: skip
            if part is not None and not isinstance(part, protocol):
                raise TypeError(
                    f"{name} must implement cpp_mujoco.physics.parts.{protocol.__name__}, "
                    f"got {type(part).__name__}"
                )
        self.model = compile_arena(build_arena(grid_map, config, fov_side))
        self.flight = Flight(
            self.model, grid_map, config, n, mdp.coverage, threads, controller=controller, wind=wind
        )
        self.unit_energy = unit_energy(config)
        drag = self.flight.half_rho_cda  # the guard reads the wind off the same law
        self.guards = (
            [ReturnGuard(grid_map, self.unit_energy, drag) for _ in range(n)]
            if config.return_guard
            else None
        )
        self.wind_directions = np.full(n, float(config.wind_direction))
        if wind_directions is not None:
            for i in np.flatnonzero(wind_directions != self.wind_directions).tolist():
                self.flight.set_wind_direction(i, wind_directions[i])
            self.wind_directions = np.asarray(wind_directions, dtype=float)
        self.guard_active = np.zeros(n, dtype=bool)
        self.tracking = np.zeros(n)
        self.crash_reason = np.full(n, None, dtype=object)

    def reset(self, mdp: GridMDP, idx: np.ndarray, rngs: list) -> None:
        """Drones ``idx`` start the episodes ``mdp`` has just reset (``rngs``: each env's
        generator, indexed like the drones)."""
        c = self.config
        for i in idx.tolist():
            row, col = divmod(int(mdp.position[i]), mdp.width)
            self.flight.reset(i, row, col, float(mdp.budget[i]) * self.unit_energy, rngs[i])
            mdp.winds.set(i, c.wind_speed, self.wind_directions[i])  # observed
            if self.guards is not None:
                self.guards[i].reset()
        self.guard_active[idx] = False
        self.tracking[idx] = 0.0
        self.crash_reason[idx] = None

    def remaining(self) -> np.ndarray:
        """J of each drone's budget left in its pack."""
        f = self.flight
        return np.maximum(f.capacity - f.energy_used, 0.0)

    def transition(self, mdp: GridMDP, actions: np.ndarray, active: np.ndarray) -> StepOutcome:
        """Safety decision (and the return guard), then the flight of every active drone; the
        outcome goes through the grid's rules (:meth:`GridMDP.apply`): the budget is the pack's
        drawable energy in units, coverage what the cameras saw."""
        f, cells = self.flight, mdp.position
        actions = actions.copy()
        if self.guards is not None:
            remaining = self.remaining()
            for i in np.flatnonzero(active).tolist():
                guard = self.guards[i]
                actions[i] = guard.filter(int(cells[i]), int(actions[i]), float(remaining[i]))
                self.guard_active[i] = guard.active
        next_cell, rejected, lands = mdp.safety.decide(cells, actions)
        kinds = np.where(lands, LAND, np.where(rejected, HOVER, MOVE))
        result = f.fly(kinds, np.where(lands | rejected, cells, next_cell), active)
        if self.guards is not None:
            for i in np.flatnonzero(active).tolist():
                self.guards[i].observe(
                    int(actions[i]), bool(rejected[i]), float(result["energy"][i]),
                    tuple(f.law.disturbance[i]),
                )  # fmt: skip
        budget = np.floor(self.remaining() / self.unit_energy + 1e-9).astype(mdp.budget.dtype)
        failed = result["failure"] != None  # noqa: E711 - elementwise over an object array
        out = mdp.apply(
            Outcome(
                next_cell=np.where(active, next_cell, cells),
                rejected=rejected & active,
                landed=result["landed"],
                spent=np.where(active, mdp.budget - budget, 0).astype(mdp.budget.dtype),
                newly_seen=result["newly_seen"],
                failed=failed,
            ),
            active,
        )
        self.tracking = np.where(active, result["tracking_error"], self.tracking)
        for i in np.flatnonzero(active).tolist():
            reason = result["failure"][i]
            self.crash_reason[i] = reason or (BUDGET_EXHAUSTED if out.crashed[i] else None)
        return out

    def infos(self) -> dict[str, np.ndarray]:
        """The physics' info keys, one entry per drone."""
        f = self.flight
        return {
            "energy_used_j": f.energy_used.copy(),
            "flight_time_s": f.state[:, 0].copy(),
            "nfz_violations": f.nfz_violations.copy(),
            "max_track_error_m": f.max_track_error.copy(),
            "tracking_error_m": self.tracking.copy(),
            "state_of_charge": f.battery.soc.copy(),
            "battery_voltage_v": f.battery.voltage(),
            "crash_reason": self.crash_reason.copy(),
            # the return guard chose this step's action; how often it did this episode
            "guard_active": self.guard_active.copy(),
            "guard_takeovers": np.array(
                [g.takeovers for g in self.guards] if self.guards else [0] * len(self.tracking)
            ),
        }
