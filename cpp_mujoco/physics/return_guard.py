"""The return guard: the safety controller's energy-aware extension that flies the UAV home.

The paper proposes it ("force navigation to the closest landing zone in the rare cases when the
RL agent misses the right moment to return"); energy-aware return-to-launch rules of the kind
Di Franco & Buttazzo (2016) describe for coverage missions decide *when* from an energy model.
Here the model is the flight itself: what moves in each heading (N, E, S, W) and hovers have
actually cost so far in this episode, shrunk towards a prior while they are few — the cost of
that kind of action (upwind, downwind, crosswind, hover) flown in MuJoCo at the wind speed the
controller's force observer has felt (``grid/wind_costs.json``, ``physics/wind_costs.py``),
counted as ``prior_weight`` samples. The way home is the path of least expected energy to any
landing cell (Dijkstra over the accepted moves); its spread adds up the moves' variances, widened
by the gusts' lag-1 correlation ρ (a sum of n AR(1) costs has at most (1+ρ)/(1−ρ) times the
variance of n independent ones). The grid's rules need one whole unit left on arrival to land,
and a landing begun then finishes on the pack's reserve.

Before each action the guard asks: after this action, would the energy left still pay for the
way home from where it leads — expected cost, scaled by how much dearer than calibrated this
flight's recent actions were (:meth:`ReturnGuard.gust_factor`: a Dryden gust lasts several
actions, and a headwind move's cost grows steeply with the gust), plus ``sigmas`` standard
deviations of this action and that way together — plus one unit and ``reserve_units``? If not, it
takes over and flies the next step of that way home (or lands). From then on it is homing: the
policy keeps control only for moves that bring home nearer and stay paid, so it still covers what
it can on the way back, but never turns away again (measured: handing control back after one
step home let policies turn away in the same gust, and each turn cost a way back). It reads
nothing a real autopilot could not know (its own energy meter, its wind estimate, the map), and
it works for any policy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from cpp_mujoco.grid.actions import LAND, NUM_ACTIONS
from cpp_mujoco.grid.safety import SafetyController
from cpp_mujoco.grid.way_home import ReturnMargin, correlation_widening
from cpp_mujoco.grid.wind import KIND_INDEX, wind_costs
from cpp_mujoco.maps import GridMap

HEADINGS = LAND  # the four moves (N, E, S, W) are actions 0..3
_UNIT_VECTORS = ((0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0))  # (east, north) per heading


@dataclass(frozen=True)
class GuardSettings(ReturnMargin):
    """How cautious the guard is: the margin of :class:`ReturnMargin` (shared with the
    wind-aware planner) and how much the calibration counts against this flight's own moves."""

    prior_weight: float = 3.0  # the calibrated cost of a kind counts as this many flown samples
    # weight of the newest action in the running ratio of what actions cost to what was
    # expected of them (a gust persists over several actions: see ReturnGuard.gust_factor)
    gust_weight: float = 0.5


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
        self.table = wind_costs()
        self.reset()

    def reset(self) -> None:
        self.samples: list[list[float]] = [[] for _ in range(NUM_ACTIONS)]  # J per action kind
        self.active = False
        self.homing = False  # the guard has taken over once: from now on it only lets go home
        self.takeovers = 0  # actions the guard chose instead of the policy this episode
        self._force, self._force_n = [0.0, 0.0], 0
        self._plan = None
        self._ratio = 1.0  # running cost / expected cost of this flight's recent actions

    # ------------------------------------------------------------------ bookkeeping
    def observe(self, action: int, rejected: bool, energy_j: float, external_force=None) -> None:
        """Record what an action drew (moves by heading, rejected actions as hovers in slot
        LAND: a landing ends the episode, so the slot is free) and the horizontal external
        force (N, world x east, y north) the controller estimated at its end, if it has one."""
        if external_force is not None:
            self._force[0] += float(external_force[0])
            self._force[1] += float(external_force[1])
            self._force_n += 1
            self._plan = None
        if action == LAND and not rejected:
            return
        kind = LAND if rejected else action
        expected = self.prior(kind)[0]
        if expected > 0:
            w = self.settings.gust_weight
            self._ratio = (1 - w) * self._ratio + w * float(energy_j) / expected
        self.samples[kind].append(float(energy_j))
        self._plan = None

    def gust_factor(self) -> float:
        """How much dearer than expected this flight's recent actions were (≥ 1): the running
        ratio of their energy to the calibrated cost at the felt mean wind. Dryden gusts are
        correlated over several actions, and a move's cost grows steeply with the headwind
        (upwind 1.4 units at 9 m/s, 2.1 at 12), so a gust that made the last actions dear
        makes the way home dear too; the guard scales the way home's expected cost by this."""
        return max(1.0, self._ratio)

    def wind_estimate(self) -> tuple[float, tuple[float, float]]:
        """(m/s, unit vector (east, north) pointing upwind) from the mean external force felt:
        quadratic drag ½ρC_dA·w² balances it, and it points where the wind blows to."""
        if self._force_n == 0:
            return 0.0, (0.0, 1.0)
        fx, fy = self._force[0] / self._force_n, self._force[1] / self._force_n
        force = math.hypot(fx, fy)
        if force == 0.0:
            return 0.0, (0.0, 1.0)
        return math.sqrt(force / self.drag_coefficient), (-fx / force, -fy / force)

    def prior(self, kind: int) -> tuple[float, float, float]:
        """(mean J, std J, gust correlation) the calibration flew for a move in heading ``kind``
        (0..3) or a hover (``LAND``) at the estimated wind; headings between upwind, across and
        downwind are weighted by the cosine of their angle to upwind."""
        speed, (ux, uy) = self.wind_estimate()
        mean, std, rho = self.table.at(np.array([min(speed, self.table.speeds[-1])]))
        mean, std = mean[0] * self.unit, std[0] * self.unit
        if kind == LAND:
            k = KIND_INDEX["hover"]
            return float(mean[k]), float(std[k]), float(rho[0])
        east, north = _UNIT_VECTORS[kind]
        c = east * ux + north * uy  # 1 upwind, 0 across, −1 downwind
        side = KIND_INDEX["upwind"] if c >= 0 else KIND_INDEX["downwind"]
        cross = KIND_INDEX["crosswind"]
        w = abs(c)
        return (
            float((1 - w) * mean[cross] + w * mean[side]),
            float((1 - w) * std[cross] + w * std[side]),
            float(rho[0]),
        )

    def stats(self, kind: int) -> tuple[float, float]:
        """(mean J, variance J²) of a move in heading ``kind`` or a hover (``LAND``): this
        flight's samples pooled with the prior counted as ``prior_weight`` samples."""
        own = np.asarray(self.samples[kind])
        prior_mean, prior_std, _ = self.prior(kind)
        n0 = self.settings.prior_weight
        mean = (own.sum() + n0 * prior_mean) / (own.size + n0)
        spread = ((own - mean) ** 2).sum() + n0 * (prior_std**2 + (prior_mean - mean) ** 2)
        return float(mean), float(spread / (own.size + n0))

    def cost(self, kind: int) -> float:
        """Estimated J of one action of ``kind`` with its margin: mean + k std, k the
        :meth:`GuardSettings.margin` at the felt wind."""
        mean, var = self.stats(kind)
        return mean + self.settings.margin(self.wind_estimate()[0])[0] * math.sqrt(var)

    def way_home(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(expected J from each cell to be over a landing cell, the variance of that, the next
        cell on that way)."""
        if self._plan is None:
            stats = [self.stats(h) for h in range(HEADINGS)]
            means = np.array([m for m, _ in stats])
            weights = means[self._edge_heading]
            graph = csr_matrix((weights, self._edges), shape=(self._cells, self._cells))
            # searching the reversed moves from the landing cells: predecessors there are the
            # next cells forward
            dist, pred, _ = dijkstra(
                graph.T, indices=self.landing, min_only=True, return_predecessors=True
            )
            variance = np.zeros(self._cells)
            move_var = np.array([v for _, v in stats])
            # the heading of each cell's step home (argmax: a cell's one move that reaches pred)
            step_var = move_var[(self.safety.next_cell[:, :HEADINGS] == pred[:, None]).argmax(1)]
            for cell in np.argsort(dist):  # nearer cells first: each adds one move to the next
                nxt = pred[cell]
                if nxt >= 0 and np.isfinite(dist[cell]):
                    variance[cell] = variance[nxt] + step_var[cell]
            self._plan = (dist, variance, pred)
        return self._plan

    # ------------------------------------------------------------------ the decision
    def filter(self, cell: int, action: int, remaining_j: float) -> int:
        """The action to fly: the policy's while the way home stays paid after it (and, once the
        guard has taken over, only if it leads home), else the guard's next step home
        (:attr:`active` says which it was this step)."""
        self.active = False
        if action == LAND and self.safety.accepted[cell, LAND]:
            return action  # landing already
        dist, variance, _ = self.way_home()
        if not np.isfinite(dist[cell]):
            return action  # no landing cell is reachable from here: nothing to guard
        nxt, rejected = self.safety.next_cell[cell, action], self.safety.rejected[cell, action]
        mean, var = self.stats(LAND if rejected else action)
        rho = self.prior(LAND)[2]
        spread = math.sqrt((var + variance[nxt]) * correlation_widening(rho))
        sigmas, reserve = self.settings.margin(self.wind_estimate()[0])
        needed = (mean + dist[nxt]) * self.gust_factor() + sigmas * spread
        paid = remaining_j >= needed + self.unit * (1.0 + reserve)
        # once homing, only moves that bring home nearer: a policy let go again after one step
        # home would turn away again, and each turn costs a way back in the same gust
        homeward = not rejected and dist[nxt] < dist[cell]
        if paid and (homeward or not self.homing):
            return action
        self.active = self.homing = True
        self.takeovers += 1
        return self._homeward(cell)

    def _homeward(self, cell: int) -> int:
        if self.safety.accepted[cell, LAND]:
            return LAND
        _, _, pred = self.way_home()
        nxt = pred[cell]
        if nxt < 0:  # no way home at all: hold position (a rejected action), the episode ends
            return LAND
        moves = np.flatnonzero(self.safety.next_cell[cell, :HEADINGS] == nxt)
        return int(moves[0])
