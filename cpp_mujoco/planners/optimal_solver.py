"""One episode's best mission: the model of :mod:`.optimal_model`, solved, flown and checked.

Two solvers take the same matrices. HiGHS (branch and cut, the default) proves the paper's maps:
its simplex solves the relaxation of a 34-unit episode of map A in seconds and the bound is then
within a target or two of the optimum, where OR-Tools CP-SAT (one worker) had not finished its
first relaxation in a minute. CP-SAT stays as the second opinion: the two must agree wherever
both prove a mission optimal.

Whatever the solver says, the mission is flown under the MDP's rules and the MDP's count is the
answer; a solver's mission that flies to fewer targets than it claims is a modelling error and
stops the run. A known mission (the hint: beam search's, or one solved before) is the first
incumbent, and where it already sees every target the budget can reach it is optimal by that
bound and no solver is called.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, replace

import highspy
import numpy as np
import ortools

from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.graph import MapGraph
from cpp_mujoco.planners.optimal_model import EpisodeModel, reachable_bound
from cpp_mujoco.planners.optimal_relaxation import peeled_paths

SOLVERS = ("highs", "cp-sat")


@dataclass(frozen=True)
class SolverOptions:
    """Which solver works on one episode, and how hard."""

    time_limit_s: float = 60.0  # per episode; the best mission found by then is kept, labelled
    workers: int = 1  # the solver's threads
    seed: int = 0  # the solver's random seed
    solver: str = "highs"  # one of SOLVERS
    relaxation_start: bool = True  # first solve the relaxation with 2 cells of memory: its
    # value a bound, the best path of its flow the first incumbent
    memory: int = 1  # cells of memory of the branch-and-cut's model (EpisodeModel): 2 gives a
    # tighter bound at every node for about four times the arcs (measured on B's open episodes:
    # proofs memory 1 missed in 25–300 s, e.g. (15, 5) with 35 units in 9 s)

    def __post_init__(self) -> None:
        if not np.isfinite(self.time_limit_s) or self.time_limit_s <= 0:
            raise ValueError(f"time limit must be a positive number, got {self.time_limit_s}")
        if int(self.workers) != self.workers or self.workers < 1:
            raise ValueError(f"workers must be an integer >= 1, got {self.workers}")
        if self.memory not in (1, 2):
            raise ValueError(f"memory must be 1 or 2 cells, got {self.memory}")
        if self.solver not in SOLVERS:
            raise ValueError(f"unknown solver {self.solver!r}; choose one of {', '.join(SOLVERS)}")


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


def solver_version(solver: str = "highs", memory: int = 1) -> str:
    """The solver and release that solved, and the model's memory where it is not the plain
    one (results name it; the first word is the solver)."""
    if solver == "highs":
        v = (highspy.HIGHS_VERSION_MAJOR, highspy.HIGHS_VERSION_MINOR, highspy.HIGHS_VERSION_PATCH)
        name = "HiGHS " + ".".join(map(str, v))
    else:
        name = f"OR-Tools CP-SAT {ortools.__version__}"
    return name if memory == 1 else f"{name}, {memory} cells of memory"


@dataclass
class _Answer:
    """What a solver returns: its status, a solution (or None) and its proven bound."""

    status: str
    x: np.ndarray | None
    bound: float


def _quiet(make):
    """``make()`` with the process's standard output shut: HiGHS prints its banner from C++ as
    it is constructed, before any option can turn it off."""
    sys.stdout.flush()
    saved, null = os.dup(1), os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    try:
        return make()
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(null)


def _highs_model(model: EpisodeModel, time_limit_s: float, threads: int, integer: bool):
    """A quiet HiGHS holding ``model`` (maximized; HiGHS minimizes), as integers or relaxed."""
    h = _quiet(highspy.Highs)
    h.setOptionValue("output_flag", False)
    h.setOptionValue("time_limit", float(time_limit_s))
    h.setOptionValue("threads", int(threads))
    n, a, inf = model.num_vars, model.A, highspy.kHighsInf
    cols = np.arange(n, dtype=np.int32)
    h.addVars(n, np.zeros(n), model.upper)
    h.changeColsCost(n, cols, -model.objective)
    if integer:
        h.changeColsIntegrality(n, cols, np.full(n, highspy.HighsVarType.kInteger))
    h.addRows(a.shape[0], np.where(np.isfinite(model.lo), model.lo, -inf),
              np.where(np.isfinite(model.hi), model.hi, inf), a.nnz,
              a.indptr[:-1].astype(np.int32), a.indices.astype(np.int32), a.data)  # fmt: skip
    return h


def _relaxation(model: EpisodeModel, time_limit_s: float) -> tuple[np.ndarray | None, float]:
    """(the linear relaxation's solution or None, its value: an upper bound; inf if unsolved)."""
    h = _highs_model(model, time_limit_s, threads=1, integer=False)
    h.setOptionValue("solver", "ipm")  # measured: 20 s where the dual simplex took minutes
    h.run()
    if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
        return None, np.inf
    return np.asarray(h.getSolution().col_value), -float(h.getInfo().objective_function_value)


def _highs(model: EpisodeModel, options: SolverOptions, hint: np.ndarray | None) -> _Answer:
    h = _highs_model(model, options.time_limit_s, options.workers, integer=True)
    h.setOptionValue("random_seed", int(options.seed))
    h.setOptionValue("mip_rel_gap", 0.0)
    h.setOptionValue("mip_abs_gap", 1.0 - 1e-6)  # the count is whole: below one target, proven
    if hint is not None:
        start = highspy.HighsSolution()
        start.col_value = hint.tolist()
        start.value_valid = True
        h.setSolution(start)
    h.run()
    code = h.getModelStatus()
    info = h.getInfo()
    found = info.primal_solution_status == 2  # kSolutionStatusFeasible
    x = np.asarray(h.getSolution().col_value) if found else None
    if code == highspy.HighsModelStatus.kInfeasible:
        return _Answer("infeasible", None, -np.inf)
    status = "optimal" if code == highspy.HighsModelStatus.kOptimal and found else (
        "feasible" if found else "unknown")  # fmt: skip
    return _Answer(status, x, -float(info.mip_dual_bound))


def _cp_sat(model: EpisodeModel, options: SolverOptions, hint: np.ndarray | None) -> _Answer:
    from ortools.sat.python import cp_model  # heavy: CP-SAT takes 1.4 s, only --solver cp-sat

    cp = cp_model.CpModel()
    x = [cp.new_int_var(0, int(u), f"x{i}") for i, u in enumerate(model.upper)]
    a = model.A
    for r in range(a.shape[0]):
        lo, hi = a.indptr[r], a.indptr[r + 1]
        expr = cp_model.LinearExpr.weighted_sum([x[j] for j in a.indices[lo:hi]],
                                                a.data[lo:hi].astype(int).tolist())  # fmt: skip
        low = int(model.lo[r]) if np.isfinite(model.lo[r]) else cp_model.INT_MIN
        high = int(model.hi[r]) if np.isfinite(model.hi[r]) else cp_model.INT_MAX
        cp.add_linear_constraint(expr, low, high)
    chosen = np.flatnonzero(model.objective)
    cp.maximize(sum(x[j] for j in chosen))
    if hint is not None:
        for var, value in zip(x, hint, strict=True):
            cp.add_hint(var, int(value))
    solver = cp_model.CpSolver()
    solver.parameters.max_time_in_seconds = float(options.time_limit_s)
    solver.parameters.num_workers = int(options.workers)
    solver.parameters.random_seed = int(options.seed)
    solver.parameters.linearization_level = 2  # measured: the bound closes far more often
    code = solver.solve(cp)
    if code == cp_model.INFEASIBLE:
        return _Answer("infeasible", None, -np.inf)
    if code not in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        return _Answer("unknown", None, float(solver.best_objective_bound))
    values = np.array([solver.value(v) for v in x], dtype=float)
    status = "optimal" if code == cp_model.OPTIMAL else "feasible"
    return _Answer(status, values, float(solver.best_objective_bound))


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
        hint_seen, hint_landed = g.fly(start, hint, seen)
        if hint_landed and hint.size <= budget:
            known = Mission(hint, hint_seen, bound, "feasible", 0.0)
            if hint_seen >= bound:
                known.status, known.time_s = "optimal", time.perf_counter() - began
                return known
    if options.relaxation_start and budget > 1:  # its best path the first incumbent, a bound
        remembered = EpisodeModel(g, start, int(budget) - 1, seen, memory=2)
        x, value = _relaxation(remembered, options.time_limit_s)
        bound = min(bound, already + int(np.floor(value + 1e-6))) if np.isfinite(value) else bound
        for walk in peeled_paths(remembered, x) if x is not None else []:
            actions = remembered.actions(walk)
            walk_seen, landed = g.fly(start, actions, seen)
            if landed and (known is None or walk_seen > known.seen):
                known, hint = Mission(actions, walk_seen, bound, "feasible", 0.0), actions
        if known is not None and known.seen >= bound:
            return _labelled(known.actions, known.seen, bound, time.perf_counter() - began)
        left = options.time_limit_s - (time.perf_counter() - began)
        options = replace(options, time_limit_s=max(left, 1.0))
    model = remembered if options.memory == 2 and options.relaxation_start and budget > 1 else (
        EpisodeModel(g, start, int(budget) - 1, seen, memory=options.memory))  # fmt: skip
    start_x = model.hint(hint) if known is not None else None
    run = _highs if options.solver == "highs" else _cp_sat
    answer = run(model, options, start_x)
    elapsed = time.perf_counter() - began
    if answer.status == "infeasible" and known is not None:
        raise RuntimeError(f"the optimal model refuses a mission the MDP flies ({hint})")
    if np.isfinite(answer.bound):  # none when the solver stopped before its first relaxation
        bound = min(already + int(np.floor(answer.bound + 1e-6)), bound)
    proven = bound
    if answer.x is None:
        if known is not None:  # no solution in time (a large map): the hint, with the bound
            return _labelled(known.actions, known.seen, proven, elapsed)
        return Mission(np.zeros(0, np.int64), already, already, answer.status, elapsed)
    actions = model.actions(answer.x)
    flown, landed = g.fly(start, actions, seen)
    value = already + int(round(float(model.objective @ answer.x)))
    # a solution that is not proven may leave a target it reveals uncounted: the MDP's count is
    # the mission's; never fewer than the model's, and the same once proven
    if not landed or flown < value or (answer.status == "optimal" and flown != value):
        raise RuntimeError(
            f"the optimal model's mission from cell {start} with budget {budget} flies to "
            f"{flown} targets (landed {landed}), the model says {value}: a modelling error"
        )
    proven = max(proven, flown)
    if known is not None and known.seen > flown:  # the solver never got to the hint's mission
        return _labelled(known.actions, known.seen, proven, elapsed)
    return _labelled(actions, flown, proven, elapsed)


def _labelled(actions: np.ndarray, seen: int, bound: int, elapsed: float) -> Mission:
    """A mission with its bound: optimal exactly when it sees as many targets as the bound."""
    bound = max(bound, seen)
    return Mission(actions, seen, bound, "optimal" if seen >= bound else "feasible", elapsed)
