"""The grid MDP's best mission as a constraint program (OR-Tools CP-SAT).

One episode — a map, a start cell, a budget and the cells already seen — is a unit of flow over
a time-expanded graph: node (t, c) is "over cell c after t actions", an arc is a move the safety
controller accepts. The model is exact under the MDP's rules:

- every action costs one unit and the last one is the landing, so a mission of ``b`` units has
  at most ``T = b − 1`` moves and ends over a landing cell;
- the field of view is marked after every action, the landing's included, but not at reset: the
  start's view counts only when the mission comes back over the start, lands there at once, or
  first hovers there (a rejected action: a move into no-fly or off the grid, or ``land`` off a
  landing cell), which costs one unit;
- a hover anywhere else marks a view already marked, so no best mission needs one; a mission that
  is done early *rests* over its landing cell until T (a rest is for good, and is not flown).

A target counts as seen when some arc *reveals* it: the arc's head sees it and its tail did not
(any arc out of the start reveals its head's whole view, since the start's view is not marked).
Counting revealing arcs rather than visits is what keeps the linear relaxation's bound useful: a
pass along a target reveals it once, not once per cell that sees it.

Pruning cuts no mission off: a cell is a node at time t only when it is at most t moves from the
start, at most ``T − t`` moves from a landing cell, and at the grid's parity (each move changes
``row + col`` by one); rests keep any parity. Where a known mission (the hint) already sees every
target the budget can reach, it is optimal by that bound and the solver is not called.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from ortools.sat.python import cp_model

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.graph import UNREACHABLE, MapGraph

STATUS = {
    cp_model.OPTIMAL: "optimal",
    cp_model.FEASIBLE: "feasible",
    cp_model.INFEASIBLE: "infeasible",
    cp_model.UNKNOWN: "unknown",
    cp_model.MODEL_INVALID: "invalid",
}


@dataclass(frozen=True)
class SolverOptions:
    """How hard CP-SAT works on one episode."""

    time_limit_s: float = 60.0  # per episode; the best mission found by then is kept, labelled
    workers: int = 1  # CP-SAT's search workers (threads)
    seed: int = 0  # CP-SAT's random seed

    def __post_init__(self) -> None:
        if not np.isfinite(self.time_limit_s) or self.time_limit_s <= 0:
            raise ValueError(f"time limit must be a positive number, got {self.time_limit_s}")
        if int(self.workers) != self.workers or self.workers < 1:
            raise ValueError(f"workers must be an integer >= 1, got {self.workers}")


@dataclass
class Mission:
    """The answer for one episode.

    ``actions`` end with the landing (empty when ``status`` is ``infeasible`` — no way home within
    the budget — or ``unknown``: no mission found in time). ``seen``: target cells the mission
    shows, those seen before included; ``bound``: a proven upper bound on any mission's.
    """

    actions: np.ndarray
    seen: int
    bound: int
    status: str
    time_s: float

    @property
    def optimal(self) -> bool:
        return self.status == "optimal"


def solver_version() -> str:
    """The OR-Tools release that solved (results name it)."""
    from ortools import __version__

    return f"OR-Tools CP-SAT {__version__}"


def _hover_action(g: MapGraph, cell: int) -> int | None:
    """An action the safety controller rejects in ``cell`` (the UAV hovers), if there is one."""
    rejected = np.flatnonzero(~g.safety.accepted[cell])
    return int(rejected[0]) if rejected.size else None


def _reach(g: MapGraph, start: int, moves: int) -> tuple[np.ndarray, np.ndarray]:
    """(moves out from the start, moves on to a landing cell) per cell, int64."""
    out = g.distance_from([start])[0].astype(np.int64)
    return out, (g.home - 1).astype(np.int64)


def reachable_bound(g: MapGraph, start: int, budget: int, seen: np.ndarray) -> int:
    """Target cells any mission can show: those in view of a cell it can fly over and still land
    (the start's own view included), capped by the camera's ``side² + side·(moves − 1)``."""
    target = g.grid_map.target.reshape(-1)
    moves = int(budget) - 1
    out, home = _reach(g, start, moves)
    flyable = (out < UNREACHABLE) & (out + home <= moves)
    visible = np.zeros(g.num_cells, dtype=bool)
    visible[g.fov_cells[flyable][g.fov_targets[flyable]]] = True
    already = int((seen & target).sum())
    new = int((visible & ~seen).sum())
    cap = g.fov_side**2 + g.fov_side * max(moves - 1, 0)
    return already + min(new, cap)


def fly(g: MapGraph, start: int, actions: np.ndarray, seen: np.ndarray) -> tuple[int, bool]:
    """(target cells seen, landed) after ``actions`` from ``start`` under the MDP's rules."""
    covered = seen.copy()
    cell, landed = start, False
    for a in actions:
        cell = int(g.safety.next_cell[cell, a])
        covered[g.fov_cells[cell]] = True
        if g.safety.lands[cell, a]:
            landed = True
            break
    target = g.grid_map.target.reshape(-1)
    return int((covered & target).sum()), landed


def solve_episode(
    g: MapGraph,
    start: int,
    budget: int,
    seen: np.ndarray | None = None,
    options: SolverOptions | None = None,
    hint: np.ndarray | None = None,
) -> Mission:
    """The mission showing the most target cells from flat cell ``start`` with ``budget`` units,
    given the (H·W,) bool cells ``seen`` already (default none: an episode's start).

    ``hint``: a known mission's actions (e.g. beam search's), the solver's first incumbent.
    """
    options = options or SolverOptions()
    began = time.perf_counter()
    seen = np.zeros(g.num_cells, bool) if seen is None else np.asarray(seen, bool).reshape(-1)
    already = int((seen & g.grid_map.target.reshape(-1)).sum())
    if budget < 1 or g.home[start] > budget:
        return Mission(np.zeros(0, np.int64), already, already, "infeasible", 0.0)
    bound = reachable_bound(g, start, budget, seen)
    if budget == 1:  # one unit: the landing, on the start (a landing cell: home[start] is 1)
        hint = np.array([LAND])
    known = None  # the hint, when it is a mission of this episode
    if hint is not None:
        hint = np.asarray(hint, dtype=np.int64)
        hint_seen, hint_landed = fly(g, start, hint, seen)
        if hint_landed and hint.size <= budget:
            known = Mission(hint, hint_seen, bound, "feasible", 0.0)
            if hint_seen >= bound:
                known.status, known.time_s = "optimal", time.perf_counter() - began
                return known
    model = _Model(g, start, int(budget) - 1, seen)
    if hint is not None:
        model.hint(hint)
    solver = cp_model.CpSolver()
    solver.parameters.max_time_in_seconds = float(options.time_limit_s)
    solver.parameters.num_workers = int(options.workers)
    solver.parameters.random_seed = int(options.seed)
    solver.parameters.linearization_level = 2  # measured: the bound closes far more often
    code = solver.solve(model.model)
    status = STATUS.get(code, "unknown")
    elapsed = time.perf_counter() - began
    if code not in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        if code == cp_model.INFEASIBLE and known is not None:
            raise RuntimeError(f"the optimal model refuses a mission the MDP flies ({hint})")
        if known is not None:  # no solution in time (a large map): the hint, with the bound
            known.time_s = elapsed
            return known
        return Mission(np.zeros(0, np.int64), already, already, status, elapsed)
    actions = model.actions(solver)
    flown, landed = fly(g, start, actions, seen)
    value = already + int(round(solver.objective_value))
    # a solution that is not proven may leave a target it reveals uncounted: the MDP's count is
    # the mission's; never fewer than the model's, and the same once proven
    if not landed or flown < value or (code == cp_model.OPTIMAL and flown != value):
        raise RuntimeError(
            f"the optimal model's mission from cell {start} with budget {budget} flies to "
            f"{flown} targets (landed {landed}), the model says {value}: a modelling error"
        )
    proven = max(min(already + int(np.floor(solver.best_objective_bound + 1e-6)), bound), flown)
    if known is not None and known.seen > flown:  # the solver never got to the hint's mission
        return Mission(known.actions, known.seen, max(proven, known.seen), "feasible", elapsed)
    status = "optimal" if flown >= proven else status
    return Mission(actions, flown, proven, status, elapsed)


def _group(keys: np.ndarray) -> dict[int, np.ndarray]:
    """{key: the indices holding it}."""
    if not keys.size:
        return {}
    order = np.argsort(keys, kind="stable")
    cuts = np.flatnonzero(np.diff(keys[order])) + 1
    return {int(keys[part[0]]): part for part in np.split(order, cuts)}


def _conflicts(g: MapGraph, start: int, moves: int, targets: np.ndarray) -> np.ndarray:
    """(k, 2) pairs of ``targets`` that no mission of ``moves`` moves sees both of: flying from
    the start over a cell that sees one, then over a cell that sees the other, then to a landing
    cell takes more moves than that, whichever comes first. A valid cut that the relaxation
    lacks (measured on B: the bound closes on most 34-unit episodes it left open)."""
    if targets.size < 2:
        return np.zeros((0, 2), dtype=np.int64)
    out, home = _reach(g, start, moves)
    cell, slot = np.nonzero(g.fov_targets)
    seen_cell = g.fov_cells[cell, slot]
    keep = np.isin(seen_cell, targets) & (out[cell] + home[cell] <= moves)
    cell, seen_cell = cell[keep], seen_cell[keep]
    viewers = np.full((targets.size, g.fov_cells.shape[1]), -1, dtype=np.int64)
    row = np.searchsorted(targets, seen_cell)
    order = np.lexsort((cell, row))
    row, cell = row[order], cell[order]
    rank = np.arange(row.size) - np.searchsorted(row, row)
    viewers[row, rank] = cell
    cells = np.unique(cell)
    if cells.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    between = g.distance_from(cells)[:, cells].astype(np.int64)  # (m, m)
    local = np.where(viewers >= 0, np.searchsorted(cells, np.maximum(viewers, 0)), -1)
    far = 10 * (moves + 1)
    to = np.where(local >= 0, out[np.maximum(viewers, 0)], far)  # (Q, 9): start → viewer
    back = np.where(local >= 0, home[np.maximum(viewers, 0)], far)  # viewer → landing
    index = np.maximum(local, 0)
    cost = np.full((targets.size, targets.size), far, dtype=np.int64)
    for i in range(viewers.shape[1]):  # (Q, Q, 9) at a time: q1 from its viewer i, q2 from any
        pair = between[index[:, i][:, None, None], index[None, :, :]]
        there = to[:, i][:, None, None] + pair + back[None, :, :]  # q1 first
        back_again = to[None, :, :] + pair + back[:, i][:, None, None]  # q2 first
        cost = np.minimum(cost, np.minimum(there, back_again).min(axis=2))
    a, b = np.nonzero(np.triu(cost > moves, k=1))
    return np.stack([targets[a], targets[b]], axis=1)


class _Model:
    """The CP-SAT model of one episode and the way back from its solution to actions."""

    def __init__(self, g: MapGraph, start: int, moves: int, seen: np.ndarray):
        self.g, self.start, self.moves = g, start, moves
        self.model = model = cp_model.CpModel()
        out, home = _reach(g, start, moves)
        t = np.arange(moves + 1)[:, None]
        moving = (out <= t) & (home <= moves - t) & ((t - out) % 2 == 0)
        resting = (out <= t) & g.grid_map.landing.reshape(1, -1)
        self._arcs(moving, resting)
        tail, head, at, rest = self.tail, self.head, self.at, self.rest
        arcs = self.arcs = [model.new_bool_var(f"a{i}") for i in range(tail.size)]
        cells = g.num_cells
        into = _group((at + 1) * cells + head)
        out_of = _group(at * cells + tail)
        model.add_exactly_one(arcs[i] for i in out_of[start])
        for node, leaving in out_of.items():
            if node >= cells:  # flow in = flow out at every node after the start
                entering = into.get(node, ())
                model.add(sum(arcs[i] for i in entering) == sum(arcs[i] for i in leaving))
        for node, entering in into.items():  # only the last layer may end a flow
            if node not in out_of and node < moves * cells:
                model.add(sum(arcs[i] for i in entering) == 0)
        self.rest_at = {(int(at[i]), int(tail[i])): int(i) for i in np.flatnonzero(rest)}
        for (step, c), i in self.rest_at.items():  # a rest is for good
            if (step + 1, c) in self.rest_at:
                model.add_implication(arcs[i], arcs[self.rest_at[step + 1, c]])
        self.hover_action = _hover_action(g, start)
        self.hover = None
        if self.hover_action is not None and moves >= 1:
            self.hover = model.new_bool_var("hover")  # its unit comes off the end
            model.add_implication(self.hover, self._rests_by(moves - 1))
        self._targets(seen)

    def _rests_by(self, step: int):
        done = self.model.new_bool_var(f"rest{step}")
        self.model.add(sum(self.arcs[i] for (s, _), i in self.rest_at.items() if s == step) == done)
        return done

    def _arcs(self, moving: np.ndarray, resting: np.ndarray) -> None:
        nxt, ok = self.g.safety.next_cell, self.g.safety.accepted
        parts = []
        for t in range(self.moves):
            here = np.array([self.start]) if t == 0 else np.flatnonzero(moving[t])
            for a in range(LAND):
                src = here[ok[here, a]]
                dst = nxt[src, a]
                keep = moving[t + 1, dst]
                parts.append((src[keep], dst[keep], t, False))
            rests = np.flatnonzero(resting[t])
            parts.append((rests, rests, t, True))
        self.tail = np.concatenate([p[0] for p in parts]).astype(np.int64)
        self.head = np.concatenate([p[1] for p in parts]).astype(np.int64)
        self.at = np.concatenate([np.full(p[0].size, p[2]) for p in parts]).astype(np.int64)
        self.rest = np.concatenate([np.full(p[0].size, p[3]) for p in parts])

    def _targets(self, seen: np.ndarray) -> None:
        g, model, arcs = self.g, self.model, self.arcs
        unseen_view = g.fov_targets & ~seen[g.fov_cells]
        reveal = unseen_view[self.head]
        later = self.at > 0
        tail_view = g.fov_cells[self.tail[later]]
        head_view = g.fov_cells[self.head[later]]
        reveal[later] &= ~(head_view[:, :, None] == tail_view[:, None, :]).any(axis=2)
        reveal[self.rest & later] = False
        arc, slot = np.nonzero(reveal)
        revealers: dict[int, list] = {
            q: [arcs[int(arc[j])] for j in js]
            for q, js in _group(g.fov_cells[self.head[arc], slot]).items()
        }
        if self.hover is not None:
            for q in g.fov_cells[self.start][unseen_view[self.start]]:
                revealers.setdefault(int(q), []).append(self.hover)
        self.new = {q: model.new_bool_var(f"s{q}") for q in revealers}
        for q, var in self.new.items():
            model.add(var <= sum(revealers[q]))
        for a, b in _conflicts(g, self.start, self.moves, np.array(sorted(self.new))):
            model.add_at_most_one(self.new[a], self.new[b])
        model.maximize(sum(self.new.values()))

    def hint(self, actions: np.ndarray) -> None:
        """Warm start from a known mission: its arcs, its hover, and the targets it shows."""
        g, ok, nxt = self.g, self.g.safety.accepted, self.g.safety.next_cell
        body = actions[:-1] if actions.size and actions[-1] == LAND else actions
        hovered = bool(body.size) and not ok[self.start, body[0]]
        path = [self.start]
        for a in body[int(hovered) :]:
            if ok[path[-1], a]:
                path.append(int(nxt[path[-1], a]))
        if len(path) - 1 + hovered > self.moves or (hovered and self.hover is None):
            return
        path += [path[-1]] * (self.moves + 1 - len(path))
        index = {
            k: i
            for i, k in enumerate(
                zip(self.at.tolist(), self.tail.tolist(), self.head.tolist(), strict=True)
            )
        }
        chosen = {index.get((t, path[t], path[t + 1])) for t in range(self.moves)}
        if None in chosen:
            return
        for i, arc in enumerate(self.arcs):
            self.model.add_hint(arc, i in chosen)
        if self.hover is not None:
            self.model.add_hint(self.hover, hovered)
        shown = set()
        for c in {*path[1:], *([self.start] if hovered else [])}:
            shown.update(g.fov_cells[c][g.fov_targets[c]].tolist())
        for q, var in self.new.items():
            self.model.add_hint(var, q in shown)

    def actions(self, solver: cp_model.CpSolver) -> np.ndarray:
        """The solution as the MDP's actions: the hover, the moves in time order, the landing."""
        chosen = np.flatnonzero([solver.boolean_value(a) for a in self.arcs])
        chosen = chosen[np.argsort(self.at[chosen], kind="stable")]
        flown = chosen[~self.rest[chosen]]
        nxt = self.g.safety.next_cell[self.tail[flown], :LAND]
        moves = (nxt == self.head[flown][:, None]).argmax(axis=1)
        hover = (
            [self.hover_action]
            if self.hover is not None and solver.boolean_value(self.hover)
            else []
        )
        return np.array([*hover, *moves.tolist(), LAND], dtype=np.int64)
