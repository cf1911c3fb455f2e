"""The grid MDP's best mission as an integer linear program.

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
``row + col`` by one); rests keep any parity. Pairs of targets no mission can both see within the
budget exclude each other (:func:`_conflicts`).

The model is plain matrices (:class:`EpisodeModel`: 0/1 variables, rows ``lo ≤ A·x ≤ hi``, a
count to maximize), so any MILP or CP solver takes it as it is (:mod:`.optimal_solver`).
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.graph import UNREACHABLE, MapGraph
from cpp_mujoco.planners.sparse_rows import Rows


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
    (the start's own view included), capped by the camera's ``side² + new·(moves − 1)`` (new:
    :attr:`~cpp_mujoco.grid.graph.MapGraph.new_per_move`)."""
    target = g.grid_map.target.reshape(-1)
    moves = int(budget) - 1
    out, home = _reach(g, start, moves)
    flyable = (out < UNREACHABLE) & (out + home <= moves)
    visible = np.zeros(g.num_cells, dtype=bool)
    visible[g.fov_cells[flyable][g.fov_targets[flyable]]] = True
    already = int((seen & target).sum())
    new = int((visible & ~seen).sum())
    cap = g.fov_side**2 + g.new_per_move * max(moves - 1, 0)
    return already + min(new, cap)


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


# the half-planes' inward normals (row, col): the axes and the diagonals
_DIRECTIONS = ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1))


class EpisodeModel:
    """One episode as a 0/1 program: maximize ``objective · x`` subject to ``lo ≤ A·x ≤ hi``
    and ``0 ≤ x ≤ upper``; variables are the arcs, the start's hover (if the start has a rejected
    action) and one per target the mission may newly see.

    ``memory=2``: a node is (time, the cell before, the cell), so an arc reveals only what neither
    of the last two cells saw. The same missions, a tighter relaxation: flying back and forth
    between two cells re-reveals nothing (with ``memory=1`` each return counts the far column
    again; map B from (15, 4) with 45 units, no half-planes: 60.00 → 56.45 targets); about four
    times the arcs."""

    def __init__(self, g: MapGraph, start: int, moves: int, seen: np.ndarray, memory: int = 1):
        if memory not in (1, 2):
            raise ValueError(f"memory must be 1 or 2 cells, got {memory}")
        self.g, self.start, self.moves, self.memory = g, start, moves, memory
        out, home = _reach(g, start, moves)
        t = np.arange(moves + 1)[:, None]
        moving = (out <= t) & (home <= moves - t) & ((t - out) % 2 == 0)
        resting = (out <= t) & g.grid_map.landing.reshape(1, -1)
        if memory == 1:
            self._arcs(moving, resting)
            self.prev = np.full(self.tail.size, -1, np.int64)
        else:
            self._arcs_remembered(moving)
        n_arcs = self.tail.size
        self.hover_action = _hover_action(g, start)
        self.has_hover = self.hover_action is not None and moves >= 1
        self.hover_var = n_arcs if self.has_hover else -1
        rows = Rows.empty()
        self.upper = self._flow(rows)
        self._targets(seen, rows, n_arcs + int(self.has_hover))
        self.num_vars = n_arcs + int(self.has_hover) + len(self.new)
        self.upper = np.concatenate([self.upper, np.ones(self.num_vars - n_arcs)])
        planes = self._half_planes(rows, self.num_vars)
        self.num_vars += planes
        self.upper = np.concatenate([self.upper, np.full(planes, float(moves))])
        self.objective = np.zeros(self.num_vars)
        self.objective[list(self.new.values())] = 1.0
        self.A = rows.matrix(self.num_vars)
        self.lo, self.hi = np.array(rows.lo, float), np.array(rows.hi, float)

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
        self.rest = np.concatenate([np.full(p[0].size, p[3]) for p in parts]).astype(bool)

    def _arcs_remembered(self, moving: np.ndarray) -> None:
        """The arcs between nodes (t, cell before, cell), layer by layer from the start's node
        (cell before −1); a rest (cell before = cell) is followed by rests only."""
        nxt, ok = self.g.safety.next_cell, self.g.safety.accepted
        landing = self.g.grid_map.landing.reshape(-1)
        prev, cell = np.array([-1]), np.array([self.start])
        parts = []
        for t in range(self.moves):
            flying = prev != cell
            for a in range(LAND):
                go = flying & ok[cell, a]
                dst = nxt[cell[go], a]
                keep = moving[t + 1, dst]
                parts.append((prev[go][keep], cell[go][keep], dst[keep], t, False))
            rests = landing[cell]
            parts.append((prev[rests], cell[rests], cell[rests], t, True))
            pairs = np.unique(np.stack([np.concatenate([p[1] for p in parts if p[3] == t]),
                                        np.concatenate([p[2] for p in parts if p[3] == t])]),
                              axis=1)  # fmt: skip
            prev, cell = pairs[0], pairs[1]
        self.prev = np.concatenate([p[0] for p in parts]).astype(np.int64)
        self.tail = np.concatenate([p[1] for p in parts]).astype(np.int64)
        self.head = np.concatenate([p[2] for p in parts]).astype(np.int64)
        self.at = np.concatenate([np.full(p[0].size, p[3]) for p in parts]).astype(np.int64)
        self.rest = np.concatenate([np.full(p[0].size, p[4]) for p in parts]).astype(bool)

    def _flow(self, rows: Rows) -> np.ndarray:
        """One unit leaves the start and is conserved at every later node; only the last layer
        may end it; a rest is for good; the hover's unit comes off the end. The arcs' upper
        bounds (0 for an arc into a node nothing leaves before the last layer)."""
        cells, n = self.g.num_cells, self.tail.size
        arcs = np.arange(n)
        if self.memory == 1:
            tail_node = self.at * cells + self.tail
            head_node = (self.at + 1) * cells + self.head
        else:  # (t, cell before, cell); the rest node of c is (t, c, c)
            tail_node = (self.at * (cells + 1) + self.prev + 1) * cells + self.tail
            head_node = ((self.at + 1) * (cells + 1) + self.tail + 1) * cells + self.head
        first = self.at == 0  # the start is the only node of layer 0
        rows.add(arcs[first], np.ones(first.sum()), 1.0, 1.0)
        leaving = self.at >= 1
        nodes = np.unique(tail_node[leaving])
        entering = np.isin(head_node, nodes)
        row_of = np.concatenate([np.searchsorted(nodes, head_node[entering]),
                                 np.searchsorted(nodes, tail_node[leaving])])  # fmt: skip
        cols = np.concatenate([arcs[entering], arcs[leaving]])
        vals = np.concatenate([np.ones(entering.sum()), -np.ones(leaving.sum())])
        rows.add(cols, vals, 0.0, 0.0, nodes.size, row_of)
        upper = np.ones(n)
        upper[~entering & (self.at + 1 < self.moves)] = 0.0
        rest = np.flatnonzero(self.rest)
        rest_at = {(int(self.at[i]), int(self.tail[i])): int(i) for i in rest}
        pairs = [(i, rest_at[s + 1, c]) for (s, c), i in rest_at.items()
                 if (s + 1, c) in rest_at and self.memory == 1]  # fmt: skip
        if pairs:  # rest(t, c) <= rest(t + 1, c); with memory a rest node has only rests
            pairs = np.array(pairs)
            rows.add(pairs.reshape(-1), np.tile([1.0, -1.0], len(pairs)), -np.inf, 0.0,
                     len(pairs), np.repeat(np.arange(len(pairs)), 2))  # fmt: skip
        if self.has_hover:  # hover <= resting by the last move
            last = rest[self.at[rest] == self.moves - 1].tolist()
            rows.add([self.hover_var, *last], [1.0] + [-1.0] * len(last), -np.inf, 0.0)
        return upper

    def _targets(self, seen: np.ndarray, rows: Rows, first_var: int) -> None:
        g = self.g
        unseen_view = g.fov_targets & ~seen[g.fov_cells]
        reveal = unseen_view[self.head]
        later = self.at > 0
        tail_view = g.fov_cells[self.tail[later]]
        head_view = g.fov_cells[self.head[later]]
        reveal[later] &= ~(head_view[:, :, None] == tail_view[:, None, :]).any(axis=2)
        older = (self.at > 1) & (self.prev >= 0)  # the cell before was flown over: seen
        prev_view = g.fov_cells[self.prev[older]]
        head_view = g.fov_cells[self.head[older]]
        reveal[older] &= ~(head_view[:, :, None] == prev_view[:, None, :]).any(axis=2)
        reveal[self.rest & later] = False
        arc, slot = np.nonzero(reveal)
        target = g.fov_cells[self.head[arc], slot]
        if self.has_hover:
            hovered = g.fov_cells[self.start][unseen_view[self.start]]
            arc = np.concatenate([arc, np.full(hovered.size, self.hover_var)])
            target = np.concatenate([target, hovered])
        targets = np.unique(target)
        self._reveal_heads = {
            int(q): np.unique(self.head[arc[(target == q) & (arc < self.tail.size)]])
            for q in targets
        }
        self._reveal_heads = {
            q: h
            for q, h in self._reveal_heads.items()
            if h.size and not (self.has_hover and q in hovered)
        }
        self.new = {int(q): first_var + k for k, q in enumerate(targets)}
        index = np.searchsorted(targets, target)  # new[q] <= the arcs revealing q
        rows.add(np.concatenate([first_var + np.arange(targets.size), arc]),
                 np.concatenate([np.ones(targets.size), -np.ones(arc.size)]), -np.inf, 0.0,
                 targets.size, np.concatenate([np.arange(targets.size), index]))  # fmt: skip
        pairs = _conflicts(g, self.start, self.moves, targets)
        if pairs.size:
            cols = first_var + np.searchsorted(targets, pairs).reshape(-1)
            rows.add(cols, np.ones(cols.size), -np.inf, 1.0, len(pairs),
                     np.repeat(np.arange(len(pairs)), 2))  # fmt: skip

    def _half_planes(self, rows: Rows, first_var: int) -> int:
        """A target is seen only if the mission enters every half-plane that holds all the
        cells revealing it and not the start: ``new[q] <= entries(H)``, one count per plane."""
        g = self.g
        width = g.grid_map.shape[1]
        flown = np.flatnonzero(~self.rest)
        tr, tc = np.divmod(self.tail[flown], width)
        hr, hc = np.divmod(self.head[flown], width)
        sr, sc = divmod(self.start, width)
        heads = self._reveal_heads
        planes: dict = {}
        self._plane_arcs: dict[int, np.ndarray] = {}
        for k, (dr, dc) in enumerate(_DIRECTIONS):
            head_p, tail_p = dr * hr + dc * hc, dr * tr + dc * tc
            start_p = dr * sr + dc * sc
            for q, cells in heads.items():
                r, c = np.divmod(cells, width)
                edge = int((dr * r + dc * c).min())
                if start_p >= edge:
                    continue
                key = (k, edge)
                if key not in planes:
                    var = first_var + len(planes)
                    crossing = flown[(tail_p < edge) & (head_p >= edge)]
                    planes[key] = var
                    self._plane_arcs[var] = crossing
                    rows.add(
                        np.concatenate([[var], crossing]),
                        np.concatenate([[1.0], -np.ones(crossing.size)]),
                        0.0,
                        0.0,
                    )
                rows.add([self.new[q], planes[key]], [1.0, -1.0], -np.inf, 0.0)
        return len(planes)

    def hint(self, actions: np.ndarray) -> np.ndarray | None:
        """A known mission as a value of every variable (a solver's first incumbent), or None
        when it is not a mission of this model (too long, or a hover the model lacks)."""
        g, ok, nxt = self.g, self.g.safety.accepted, self.g.safety.next_cell
        body = actions[:-1] if actions.size and actions[-1] == LAND else actions
        hovered = bool(body.size) and not ok[self.start, body[0]]
        path = [self.start]
        for a in body[int(hovered) :]:
            if ok[path[-1], a]:
                path.append(int(nxt[path[-1], a]))
        if len(path) - 1 + hovered > self.moves or (hovered and not self.has_hover):
            return None
        path += [path[-1]] * (self.moves + 1 - len(path))
        index = {
            k: i
            for i, k in enumerate(
                zip(self.at.tolist(), self.prev.tolist(), self.tail.tolist(),
                    self.head.tolist(), strict=True)
            )
        }  # fmt: skip
        before = [-1, *path] if self.memory == 2 else [-1] * (len(path) + 1)
        chosen = [index.get((t, before[t], path[t], path[t + 1])) for t in range(self.moves)]
        if None in chosen:
            return None
        x = np.zeros(self.num_vars)
        x[chosen] = 1.0
        if hovered:
            x[self.hover_var] = 1.0
        for c in {*path[1:], *([self.start] if hovered else [])}:
            for q in g.fov_cells[c][g.fov_targets[c]].tolist():
                if q in self.new:
                    x[self.new[q]] = 1.0
        for var, crossing in self._plane_arcs.items():
            x[var] = x[crossing].sum()
        return x

    def actions(self, x: np.ndarray) -> np.ndarray:
        """A solution as the MDP's actions: the hover, the moves in time order, the landing."""
        chosen = np.flatnonzero(x[: self.tail.size] > 0.5)
        chosen = chosen[np.argsort(self.at[chosen], kind="stable")]
        flown = chosen[~self.rest[chosen]]
        nxt = self.g.safety.next_cell[self.tail[flown], :LAND]
        moves = (nxt == self.head[flown][:, None]).argmax(axis=1)
        hover = [self.hover_action] if self.has_hover and x[self.hover_var] > 0.5 else []
        return np.array([*hover, *moves.tolist(), LAND], dtype=np.int64)
