"""The return guard: the safety controller's energy-aware extension that flies the UAV home.

The paper proposes it ("force navigation to the closest landing zone in the rare cases when the
RL agent misses the right moment to return"); energy-aware return-to-launch rules of the kind
Di Franco & Buttazzo (2016) describe for coverage missions decide *when* from an energy model.
Here the model is the flight itself: what moves in each heading (N, E, S, W) and hovers have
actually cost so far in this episode. A heading's estimated cost is its mean plus ``sigmas``
standard deviations (floored at ``min_spread`` units, since a few samples understate the
spread); an unflown heading costs the dearest flown one, raised by how much it faces the wind
the controller's force observer has felt (an upwind leg costs more), and before any move a
calibrated calm unit. The way home is the cheapest path to any landing cell under those costs
(Dijkstra over the accepted moves), plus one unit: the grid's rules need one unit shown to land,
and a landing begun then finishes on the pack's reserve.

Before each action the guard asks: after this action's estimated cost, would the energy left
still pay for the way home from where it leads, plus ``reserve_units``? If not, it takes over
and flies the next step of that way home (or lands). It intervenes no more than that: a policy
heading home on its own keeps control, so it still covers what it meant to on the way back, and
a policy that turns away again is overruled again. It reads nothing a real autopilot could not
know (its own energy meter, the map), and it works for any policy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from cpp_mujoco.grid.actions import LAND, NUM_ACTIONS
from cpp_mujoco.grid.safety import SafetyController
from cpp_mujoco.maps import GridMap

HEADINGS = LAND  # the four moves (N, E, S, W) are actions 0..3
_UNIT_VECTORS = ((0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0))  # (east, north) per heading
_REFERENCE_WIND = 9.0  # m/s, where upwind_gain is measured


@dataclass(frozen=True)
class GuardSettings:
    """How cautious the guard is (defaults measured: README "Flying in wind")."""

    sigmas: float = 2.0  # a heading's cost: mean + sigmas · std of its moves this flight
    min_spread: float = 0.01  # units: the std is at least this (a few samples understate it)
    reserve_units: float = 0.1  # units kept beyond the estimated way home
    # an unflown heading costs the dearest flown one × (1 + upwind_gain·(ŵ / 9 m/s)²·cos θ),
    # ŵ the wind the controller's force observer has felt, θ the heading's angle to upwind:
    # steady 9 m/s makes an upwind move 1.21 × a downwind one, 12 m/s 1.41 × (scripts/transfer.py)
    upwind_gain: float = 0.25


class ReturnGuard:
    """Per-episode energy bookkeeping and the take-over decision for one map."""

    def __init__(
        self,
        grid_map: GridMap,
        unit_energy: float,
        drag_coefficient: float,
        settings: GuardSettings | None = None,
    ):
        """``drag_coefficient``: ½ρC_dA of the airframe (N per (m/s)²)."""
        self.settings = settings or GuardSettings()
        self.unit = float(unit_energy)
        self.drag_coefficient = float(drag_coefficient)
        self.safety = SafetyController(grid_map)
        accepted = self.safety.accepted[:, :HEADINGS]
        src = np.repeat(np.arange(accepted.shape[0]), HEADINGS)[accepted.reshape(-1)]
        self._edge_heading = np.tile(np.arange(HEADINGS), accepted.shape[0])[accepted.reshape(-1)]
        self._edges = (src, self.safety.next_cell[:, :HEADINGS][accepted])
        self._cells = accepted.shape[0]
        self.landing = np.flatnonzero(grid_map.landing.reshape(-1))
        self.reset()

    def reset(self) -> None:
        self.samples: list[list[float]] = [[] for _ in range(NUM_ACTIONS)]  # J per action kind
        self.active = False
        self.takeovers = 0  # actions the guard chose instead of the policy this episode
        self._force, self._force_n = [0.0, 0.0], 0
        self._plan = None

    # ------------------------------------------------------------------ bookkeeping
    def observe(self, action: int, rejected: bool, energy_j: float, external_force=None) -> None:
        """Record what an action drew (moves by heading, rejected actions as hovers in slot
        LAND: a landing ends the episode, so the slot is free) and the horizontal external
        force (N, world x east, y north) the controller estimated at its end, if it has one."""
        if external_force is not None:
            self._force[0] += float(external_force[0])
            self._force[1] += float(external_force[1])
            self._force_n += 1
        if action == LAND and not rejected:
            return
        self.samples[LAND if rejected else action].append(float(energy_j))
        self._plan = None

    def cost(self, kind: int) -> float:
        """Estimated J of a move in heading ``kind`` (0..3) or a hover (``LAND``)."""
        s = self.settings
        own = self.samples[kind]
        if len(own) == 0:
            flown = [np.mean(v) + s.sigmas * self._spread(v) for v in self.samples[:HEADINGS] if v]
            return self._upwind_factor(kind) * max(flown) if flown else self.unit
        return float(np.mean(own) + s.sigmas * self._spread(own))

    def _upwind_factor(self, heading: int) -> float:
        """How much dearer an unflown heading may be, from the wind felt so far."""
        if self._force_n == 0 or heading == LAND:
            return 1.0
        fx, fy = self._force[0] / self._force_n, self._force[1] / self._force_n
        force = math.hypot(fx, fy)
        if force == 0.0:
            return 1.0
        wind = math.sqrt(force / self.drag_coefficient)  # m/s: drag ½ρC_dA·w² balances it
        east, north = _UNIT_VECTORS[heading]
        upwind = -(east * fx + north * fy) / force  # the force points where the wind blows to
        gain = self.settings.upwind_gain * (wind / _REFERENCE_WIND) ** 2
        return 1.0 + gain * max(upwind, 0.0)

    def _spread(self, values: list[float]) -> float:
        std = float(np.std(values)) if len(values) > 1 else 0.0
        return max(std, self.settings.min_spread * self.unit)

    def way_home(self) -> tuple[np.ndarray, np.ndarray]:
        """(J from each cell to be over a landing cell, the next cell on that way)."""
        if self._plan is None:
            weights = np.array([self.cost(h) for h in range(HEADINGS)])[self._edge_heading]
            graph = csr_matrix((weights, self._edges), shape=(self._cells, self._cells))
            # searching the reversed moves from the landing cells: predecessors there are the
            # next cells forward
            dist, pred, _ = dijkstra(
                graph.T, indices=self.landing, min_only=True, return_predecessors=True
            )
            self._plan = (dist, pred)
        return self._plan

    # ------------------------------------------------------------------ the decision
    def filter(self, cell: int, action: int, remaining_j: float) -> int:
        """The action to fly: the policy's while the way home stays paid after it, else the
        guard's next step home (:attr:`active` says which it was this step)."""
        self.active = False
        if action == LAND and self.safety.accepted[cell, LAND]:
            return action  # landing already
        dist, _ = self.way_home()
        if not np.isfinite(dist[cell]):
            return action  # no landing cell is reachable from here: nothing to guard
        nxt, rejected = self.safety.next_cell[cell, action], self.safety.rejected[cell, action]
        spend = self.cost(LAND if rejected else action)
        if remaining_j - spend >= dist[nxt] + self.unit * (1.0 + self.settings.reserve_units):
            return action
        self.active = True
        self.takeovers += 1
        return self._homeward(cell)

    def _homeward(self, cell: int) -> int:
        if self.safety.accepted[cell, LAND]:
            return LAND
        dist, pred = self.way_home()
        nxt = pred[cell]
        if nxt < 0:  # no way home at all: hold position (a rejected action), the episode ends
            return LAND
        moves = np.flatnonzero(self.safety.next_cell[cell, :HEADINGS] == nxt)
        return int(moves[0])
