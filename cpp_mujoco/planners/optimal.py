"""The exact planner: every episode's best mission, solved (:mod:`.optimal_model`), cached
(:mod:`.optimum_cache`) and flown.

:func:`solve_episodes` solves a protocol's episodes — beam search's missions are the warm starts,
computed for all of them at once — over ``jobs`` processes, saving the cache as it goes. A worker
that fails stops the run with its error; what was solved before is kept.
:class:`OptimalPlanner` is the policy: at an episode's first step it takes the cached mission or
solves one, then follows it; if the UAV is not over the plan's cell or has too little budget left
to finish the plan (the physics backend), it solves again from where it is, with what it has seen.
"""

from __future__ import annotations

import multiprocessing
import signal
import time
from dataclasses import asdict

import numpy as np
from tqdm import tqdm

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.graph import MapGraph, build_graph, graph_from_observation
from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.maps import GridMap
from cpp_mujoco.planners.beam_search import BeamSearchPlanner
from cpp_mujoco.planners.optimal_search import CoverageSearch, SearchOptions
from cpp_mujoco.planners.optimal_solver import Mission, SolverOptions, solve_episode, solver_version
from cpp_mujoco.planners.rollout import decode_observation, rollout
from cpp_mujoco.protocol.optimum_cache import OptimumCache, tighten

SAVE_EVERY_S = 10.0  # an interrupted solve loses at most this much finished work


def beam_missions(
    grid_map: GridMap, cells: np.ndarray, budgets: np.ndarray, fov_side: int = 3
) -> list[np.ndarray]:
    """Beam search's mission (actions to its landing) for each (flat cell, budget) episode."""
    g = build_graph(grid_map, fov_side)
    coverage = np.zeros((cells.size, g.num_cells), dtype=bool)
    config = GridConfig(fov_side=fov_side)
    actions, _, taken = rollout(
        grid_map, BeamSearchPlanner(fov_side=fov_side), cells, budgets, coverage, config
    )
    return [actions[i, : taken[i]] for i in range(cells.size)]


def trajectory_actions(g: MapGraph, cells: np.ndarray) -> np.ndarray:
    """A landed episode's actions from the cells it was over (a result's trajectory, -1 after
    the end): the moves between them, a rejected action where it stayed, then the landing."""
    cells = np.asarray(cells, dtype=np.int64)
    cells = cells[cells >= 0][:-1]  # the last entry is where it landed: the landing's own
    actions = []
    for here, there in zip(cells[:-1], cells[1:], strict=True):
        moves = np.flatnonzero(g.safety.next_cell[here, :LAND] == there)
        stays = np.flatnonzero(~g.safety.accepted[here])
        actions.append(int(moves[0]) if here != there else int(stays[0]))
    return np.array(actions + [LAND], dtype=np.int64)


_worker_graph: MapGraph | None = None


def _init_worker(grid_map: GridMap, fov_side: int) -> None:
    """A worker ends quietly when the pool terminates it; Ctrl-C is the main process's to
    handle (it saves the cache, then terminates the pool)."""
    global _worker_graph
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _worker_graph = build_graph(grid_map, fov_side)


def _solve_one(args) -> Mission:
    cell, budget, hint, options = args
    return solve_episode(_worker_graph, cell, budget, options=options, hint=hint)


def solve_episodes(
    grid_map: GridMap,
    starts: np.ndarray,
    budgets: np.ndarray,
    options: SolverOptions | None = None,
    cache: OptimumCache | None = None,
    jobs: int = 1,
    progress: bool = False,
    fov_side: int = 3,
) -> list[dict]:
    """Each (start (row, col), budget) episode's cache entry, solving those not yet known (or
    known only from a shorter time limit and not proven). ``jobs`` processes solve at once."""
    options = options or SolverOptions()
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    cache = cache or OptimumCache.in_memory(grid_map, fov_side)
    starts = np.asarray(starts, dtype=np.int64).reshape(-1, 2)
    budgets = np.asarray(budgets, dtype=np.int64).reshape(-1)
    keys = [(int(s[0]), int(s[1]), int(b)) for s, b in zip(starts, budgets, strict=True)]
    first = {key: i for i, key in reversed(list(enumerate(keys)))}  # each episode once
    solver = solver_version(options.solver, options.memory)
    todo = sorted(
        i
        for i in first.values()
        if not cache.usable(tuple(starts[i]), int(budgets[i]), solver, options.time_limit_s)
    )  # fmt: skip
    if todo:
        cells = starts[todo, 0] * grid_map.shape[1] + starts[todo, 1]
        hints = beam_missions(grid_map, cells, budgets[todo], fov_side)
        for k, i in enumerate(todo):  # a mission known from a shorter limit starts the search
            old = cache.get(tuple(starts[i]), int(budgets[i]))
            if old is not None and old["actions"]:
                hints[k] = np.asarray(old["actions"], dtype=np.int64)
        work = [
            (int(c), int(budgets[i]), h, options)
            for c, i, h in zip(cells, todo, hints, strict=True)
        ]
        saved = time.monotonic()
        bar = tqdm(total=len(work), desc=f"optimum {grid_map.label}", disable=not progress)
        pool = multiprocessing.get_context("fork").Pool(jobs, _init_worker, (grid_map, fov_side))
        try:
            for i, mission in zip(todo, pool.imap(_solve_one, work), strict=True):
                cache.put(tuple(starts[i]), int(budgets[i]), mission,
                          options.time_limit_s, options.workers, solver)  # fmt: skip
                bar.update()
                if cache.path is not None and time.monotonic() - saved > SAVE_EVERY_S:
                    cache.save()
                    saved = time.monotonic()
        finally:  # a failed worker or an interruption stops every worker now; the rest is kept
            pool.terminate()
            pool.join()
            bar.close()
            if cache.path is not None:
                cache.save()
    return [cache.get(tuple(s), int(b)) for s, b in zip(starts, budgets, strict=True)]


def close_gaps(
    grid_map: GridMap,
    starts: np.ndarray,
    budgets: np.ndarray,
    options: SearchOptions,
    cache: OptimumCache,
    progress: bool = False,
) -> list[dict]:
    """Close the open episodes among these with the exact search (:mod:`.optimal_search`): each
    is asked whether a mission sees its bound's count — a mission found is optimal, a proof that
    none exists lowers the bound by one — until the two meet or a question runs out of time.
    The episodes must be in the cache (solved first); the search sees with the cache's view.

    The largest budgets go first: the cache's :func:`tighten` carries a bound to every smaller
    budget and to the nearby starts, so one proof often closes many episodes."""
    keys = sorted(
        {(int(b), int(s[0]), int(s[1])) for s, b in zip(starts, budgets, strict=True)},
        reverse=True,
    )
    unsolved = [(r, c, b) for b, r, c in keys if cache.get((r, c), b) is None]
    if unsolved:
        raise ValueError(
            f"{len(unsolved)} of these episodes are not in the optimum cache (e.g. start "
            f"{unsolved[0][:2]}, {unsolved[0][2]} units): solve them first (`cpp-mujoco optimum` "
            "without --close-gaps)"
        )
    g = build_graph(grid_map, cache.fov_side)
    width = grid_map.shape[1]
    searches: dict[tuple[int, int], CoverageSearch] = {}
    for budget, row, col in tqdm(keys, desc=f"gaps {grid_map.label}", disable=not progress):
        entry = cache.get((row, col), budget)
        while entry["status"] == "feasible":
            search = searches.get((row, col))
            if search is None:
                search = searches[(row, col)] = CoverageSearch(g, row * width + col, options)
            answer = search.ask(budget, entry["bound"])
            if answer.status == "unknown":
                break
            if answer.seen > entry["bound"]:
                raise RuntimeError(
                    f"episode {(row, col, budget)}: the search flew a mission to {answer.seen} "
                    f"targets, above the cache's proven bound of {entry['bound']}"
                )
            if answer.status == "found":
                mission = Mission(answer.actions, answer.seen, entry["bound"], "feasible",
                                  answer.time_s)  # fmt: skip
            else:
                mission = Mission(np.asarray(entry["actions"], dtype=np.int64), entry["seen"],
                                  entry["bound"] - 1, "feasible", answer.time_s)  # fmt: skip
            cache.put((row, col), budget, mission, options.time_limit_s, 1, search.name)
            if cache.path is not None:
                cache.save()  # tightened: the proof reaches the other episodes now
            else:
                tighten(cache.entries, g)
            entry = cache.get((row, col), budget)
    return [cache.get(tuple(s), int(b)) for s, b in zip(starts, budgets, strict=True)]


class OptimalPlanner:
    """The best mission per episode, from ``cache`` (an :class:`OptimumCache` folder) or solved."""

    name = "optimal"

    def __init__(self, options: SolverOptions | None = None, cache_folder=None,
                 jobs: int = 1, fov_side: int = 3):  # fmt: skip
        self.options = options or SolverOptions()
        self.cache_folder = cache_folder
        self.jobs = jobs
        self.fov_side = fov_side
        self.statuses: dict[str, int] = {}
        self.reset(0)

    def identity(self) -> dict:
        """What results record of this planner: the solver, its limits, and what it proved (the
        statuses of the missions this process planned; none where worker processes flew)."""
        out = {
            **asdict(self.options),
            "solver": solver_version(self.options.solver, self.options.memory),
        }
        if self.statuses:
            out["statuses"] = dict(sorted(self.statuses.items()))
        return out

    def reset(self, num_episodes: int, seed: int | None = None) -> None:
        self._plans: list[np.ndarray] | None = None
        self._cells: list[np.ndarray] = []
        self._cursor = np.zeros(0, dtype=np.int64)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        g = graph_from_observation(obs, self.fov_side)
        pos, budget, coverage = decode_observation(obs)
        n = pos.size
        if self._plans is None or len(self._plans) != n:
            self._plan_episodes(g, pos, budget, coverage)
        out = np.full(n, LAND, dtype=np.int64)
        for i in range(n):
            k = self._cursor[i]
            plan = self._plans[i]
            # off the plan's cell, or too little budget left to finish it (physics: a move may
            # cost more than a unit): solve again from here
            if k < plan.size and (self._cells[i][k] != pos[i] or budget[i] < plan.size - k):
                self._replan(g, i, pos[i], budget[i], coverage[i])
                k, plan = 0, self._plans[i]
            if k < plan.size:
                out[i] = plan[k]
            self._cursor[i] += 1
        return out

    def _plan_episodes(self, g: MapGraph, pos, budget, coverage) -> None:
        grid_map = g.grid_map
        fresh = ~coverage.any(axis=1) & grid_map.landing.reshape(-1)[pos]
        self._plans = [np.zeros(0, np.int64)] * pos.size
        self._cells = [np.zeros(0, np.int64)] * pos.size
        self._cursor = np.zeros(pos.size, dtype=np.int64)
        if fresh.any():
            rows = np.flatnonzero(fresh)
            starts = np.stack(np.divmod(pos[rows], grid_map.shape[1]), axis=1)
            cache = OptimumCache(self.cache_folder, grid_map, self.fov_side) if (
                self.cache_folder is not None) else None  # fmt: skip
            entries = solve_episodes(grid_map, starts, budget[rows], self.options, cache,
                                     self.jobs, fov_side=self.fov_side)  # fmt: skip
            for i, entry in zip(rows, entries, strict=True):
                self._count(entry["status"])
                self._set(g, i, pos[i], np.asarray(entry["actions"], dtype=np.int64))
        for i in np.flatnonzero(~fresh):
            self._replan(g, i, pos[i], budget[i], coverage[i])

    def _replan(self, g: MapGraph, i: int, cell, budget, coverage) -> None:
        hint = beam_missions_from(g, cell, budget, coverage, self.fov_side)
        mission = solve_episode(g, int(cell), int(budget), coverage, self.options, hint)
        self._count(mission.status)
        self._cursor[i] = 0
        self._set(g, i, cell, mission.actions)

    def _set(self, g: MapGraph, i: int, cell, actions: np.ndarray) -> None:
        cells = [int(cell)]
        for a in actions[:-1]:
            cells.append(int(g.safety.next_cell[cells[-1], a]))
        self._plans[i] = actions
        self._cells[i] = np.array(cells, dtype=np.int64)

    def _count(self, status: str) -> None:
        self.statuses[status] = self.statuses.get(status, 0) + 1


def beam_missions_from(g: MapGraph, cell, budget, coverage, fov_side: int) -> np.ndarray:
    """Beam search's mission from a mid-episode state (a replan's warm start)."""
    actions, _, taken = rollout(
        g.grid_map, BeamSearchPlanner(fov_side=fov_side), np.array([cell]), np.array([budget]),
        np.asarray(coverage, dtype=bool)[None, :], GridConfig(fov_side=fov_side),
    )  # fmt: skip
    return actions[0, : taken[0]]
