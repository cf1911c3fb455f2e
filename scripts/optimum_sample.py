"""The policies against the best missions on a random sample of a held-out set's episodes.

    python scripts/optimum_sample.py --map-set heldout16-v1 --episodes 120 --time-limit 10 --jobs 2
    python scripts/optimum_sample.py --map-set heldout16-v1 --render   # the table from the file
    python scripts/optimum_sample.py --map-set city32-v1 --episodes 12 --time-limit 20 \\
        --policies safe-greedy beam-search
    python scripts/optimum_sample.py --map-set heldout16-v1 --beam-width 512   # a wider beam too
    python scripts/optimum_sample.py --map-set heldout16-v1 --close-gaps 60   # then the search

Draws episodes uniformly over the set's protocol (a map, one of its landing cells, a budget of its
size class; seeded), flies safe greedy, beam search, the general agent and the general agent
searching with its values (``general+value-beam``) on them, solves each
into the optimum cache (results/optimum/) from the best of their missions (with
``--beam-width W`` also a beam of W paths, whose missions re-open the cached episodes where
they see more than the cached best; with ``--close-gaps S`` the episodes still open then go to the
exact search, S seconds per question: planners/optimal_search.py), and writes
results/optimum_<set>.json: per policy its mean coverage, its mean gap to the best missions found
with the gap's standard error, and what it was (its file's digest, its rules:
``policy_identities``);
how many of the best missions are proven, with the mean bound.
The table in docs/optimum.md is written from that file (``--render``).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "optimum.md"
POLICIES = ("safe-greedy", "beam-search", "general", "general+value-beam")


def make_policy(name: str):
    """A policy of the table by its name: a planner, the general agent, or the general agent
    searching with its values (:mod:`cpp_mujoco.agent.value_beam`)."""
    from cpp_mujoco.agent import load_agent
    from cpp_mujoco.agent.value_beam import ValueBeamAgent
    from cpp_mujoco.planners import make_planner

    if name == "general+value-beam":
        return ValueBeamAgent(load_agent("general"))
    return load_agent(name) if name == "general" else make_planner(name)


def result_path(name: str) -> Path:
    return ROOT / "results" / f"optimum_{name}.json"


def draw(maps, episodes: int, seed: int) -> list[tuple[int, tuple[int, int], int]]:
    from cpp_mujoco.map_sets.size_classes import budget_range

    rng = np.random.default_rng(seed)
    out = []
    for _ in range(episodes):
        k = int(rng.integers(len(maps)))
        cells = np.argwhere(maps[k].landing)
        row, col = cells[rng.integers(len(cells))]
        lo, hi = budget_range(maps[k].shape[0])
        out.append((k, (int(row), int(col)), int(rng.integers(lo, hi + 1))))
    return out


def better_hint(entry: dict | None, hint_seen: float) -> bool:
    """A cached episode, not proven, whose best mission sees fewer targets than the hint."""
    return entry is not None and entry["status"] == "feasible" and hint_seen > entry["seen"] + 0.5


def earlier_search(map_set: str, solvers: dict) -> float | None:
    """The search time limit the sample's file records, where that search still proves some of
    its best missions in the cache (a run without ``--close-gaps`` keeps them)."""
    path = result_path(map_set)
    if not path.is_file() or not any(s.startswith("key-target search") for s in solvers):
        return None
    return json.loads(path.read_text()).get("search_time_limit_s")


def solve_one(task):
    """One sampled episode's best mission, warm-started from the best policy's."""
    from cpp_mujoco.grid.graph import build_graph
    from cpp_mujoco.planners.optimal_solver import solve_episode

    grid_map, (row, col), budget, options, hint = task
    cell = row * grid_map.shape[1] + col
    return solve_episode(build_graph(grid_map), cell, budget, options=options, hint=hint)


def close_one(task) -> None:
    """One map's open episodes to the exact search, its cache file saved as they close."""
    from cpp_mujoco.planners.optimal import close_gaps
    from cpp_mujoco.planners.optimal_search import SearchOptions
    from cpp_mujoco.protocol.optimum_cache import OptimumCache

    grid_map, episodes, limit = task
    cache = OptimumCache(ROOT / "results" / "optimum", grid_map)
    starts = np.array([s for s, _ in episodes])
    budgets = np.array([b for _, b in episodes])
    close_gaps(grid_map, starts, budgets, SearchOptions(limit), cache)


def run(args) -> dict:
    from cpp_mujoco.grid.graph import build_graph
    from cpp_mujoco.map_sets.sets import load_map_set
    from cpp_mujoco.planners import BeamSearchPlanner
    from cpp_mujoco.planners.optimal import trajectory_actions
    from cpp_mujoco.planners.optimal_solver import SolverOptions, solver_version
    from cpp_mujoco.protocol.evaluate import evaluate
    from cpp_mujoco.protocol.optimum_cache import OptimumCache
    from cpp_mujoco.protocol.policy import policy_identity
    from cpp_mujoco.util.io import atomic_write_text

    maps = load_map_set(args.map_set)
    sample = draw(maps, args.episodes, args.seed)
    hints = [(-1.0, None)] * len(sample)
    flown = {name: make_policy(name) for name in args.policies}
    if args.beam_width:
        wide = BeamSearchPlanner(width=args.beam_width)
        flown[wide.name] = wide
    coverage = {}
    for name, policy in flown.items():
        cov = []
        for j, (k, start, budget) in enumerate(sample):
            result = evaluate(policy, maps[k], budgets=[budget])
            i = int(np.flatnonzero((result.starts == start).all(axis=1))[0])
            cov.append(float(result.coverage[i]))
            if result.landed[i] and cov[-1] > hints[j][0]:  # the best policy's mission
                g = build_graph(maps[k])
                hints[j] = (cov[-1], trajectory_actions(g, result.trajectories[i]))
        coverage[name] = cov
    options = SolverOptions(time_limit_s=args.time_limit)
    caches = {}
    for k, _, _ in sample:
        caches.setdefault(k, OptimumCache(ROOT / "results" / "optimum", maps[k]))
    solver = solver_version(options.solver)
    todo = [
        (maps[k], s, b, options, hints[j][1]) for j, (k, s, b) in enumerate(sample)
        if not caches[k].usable(s, b, solver, options.time_limit_s)
        or better_hint(caches[k].get(s, b), hints[j][0] * maps[k].target.sum())
    ]  # fmt: skip
    with multiprocessing.get_context("fork").Pool(args.jobs) as pool:
        for (grid_map, s, b, *_), mission in zip(todo, pool.imap(solve_one, todo), strict=True):
            k = next(i for i, m in enumerate(maps) if m is grid_map)
            caches[k].put(s, b, mission, options.time_limit_s, options.workers, solver)
            caches[k].save()
    if args.close_gaps:
        open_ = {}  # per map, one worker: its cache file has one writer
        for k, s, b in sample:
            if caches[k].get(s, b)["status"] == "feasible":
                open_.setdefault(k, []).append((s, b))
        tasks = [(maps[k], episodes, args.close_gaps) for k, episodes in open_.items()]
        with multiprocessing.get_context("fork").Pool(args.jobs) as pool:
            for _ in pool.imap_unordered(close_one, tasks):
                pass
        caches = {k: OptimumCache(ROOT / "results" / "optimum", maps[k]) for k in caches}
    best, bound, status, solvers = [], [], [], {}
    for k, start, budget in sample:
        entry = caches[k].get(start, budget)
        solvers[entry["solver"]] = solvers.get(entry["solver"], 0) + 1
        targets = maps[k].target.sum()
        best.append(entry["seen"] / targets)
        bound.append(entry["bound"] / targets)
        status.append(entry["status"])
    best_a = np.array(best)
    data = {
        "map_set": args.map_set,
        "episodes": [
            {"map": maps[k].label, "map_digest": maps[k].digest, "start": s, "budget": b}
            for k, s, b in sample
        ],
        "seed": args.seed,
        "solver": solver_version(options.solver),
        "solvers": dict(sorted(solvers.items())),  # which solver's mission each episode keeps
        "time_limit_s": args.time_limit,
        "search_time_limit_s": args.close_gaps or earlier_search(args.map_set, solvers),
        "statuses": {s: status.count(s) for s in sorted(set(status))},
        "best_found": float(best_a.mean()),
        "bound": float(np.mean(bound)),
        "policy_identities": {name: policy_identity(p) for name, p in flown.items()},
        "policies": {
            name: {
                "coverage": float(np.mean(cov)),
                "gap_to_best": float((np.array(cov) - best_a).mean()),
                "gap_standard_error": float(
                    (np.array(cov) - best_a).std(ddof=1) / np.sqrt(len(cov))
                ),  # fmt: skip
            }
            for name, cov in coverage.items()
        },
    }
    atomic_write_text(result_path(args.map_set), json.dumps(data, indent=1))
    return data


def render(data: dict) -> str:
    from cpp_mujoco.review.optimum_table import optimum_sample_table

    return optimum_sample_table(data)


def markers(name: str) -> tuple[str, str]:
    return f"<!-- optimum-{name}:begin -->", f"<!-- optimum-{name}:end -->"


def write_doc(data: dict, check: bool = False) -> int:
    begin, end = markers(data["map_set"])
    text = DOC.read_text()
    if begin not in text:
        raise SystemExit(f"optimum_sample.py: {DOC} lacks the markers {begin} … {end}")
    before, rest = text.split(begin, 1)
    after = rest.split(end, 1)[1]
    wanted = f"{before}{begin}\n{render(data)}\n{end}{after}"
    if check:
        return int(wanted != text)
    if wanted != text:
        from cpp_mujoco.util.io import atomic_write_text

        atomic_write_text(DOC, wanted)
    return 0


def main(argv=None) -> int:
    from cpp_mujoco.cli.options import int_at_least, positive_seconds

    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--map-set", default="heldout16-v1")
    p.add_argument("--episodes", type=int, default=120)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--time-limit", type=positive_seconds, default=10.0)
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument(
        "--policies", nargs="+", default=list(POLICIES), choices=POLICIES,
        help="the policies flown beside the best missions (the general agent refuses maps with "
        "obstacles: leave it out there)",
    )  # fmt: skip
    p.add_argument(
        "--beam-width", type=int_at_least(0), default=0,
        help="also fly beam search of this many paths per episode (0: none): a policy of its "
        "own in the table, and its missions warm-start the solver where they see more",
    )  # fmt: skip
    p.add_argument(
        "--close-gaps", type=positive_seconds, metavar="S",
        help="then close the open episodes with the exact search, S seconds per question",
    )  # fmt: skip
    p.add_argument("--render", action="store_true", help="only write the doc's table")
    p.add_argument("--check", action="store_true", help="exit 1 if the doc's table drifted")
    args = p.parse_args(argv)
    if args.render or args.check:
        data = json.loads(result_path(args.map_set).read_text())
    else:
        data = run(args)
    code = write_doc(data, check=args.check)
    if not args.check:
        print(render(data))
    return code


if __name__ == "__main__":
    sys.exit(main())
