"""The exact planner's answers summarised: how many episodes were proven, the best missions'
mean coverage beside the proven bound, and what solving cost."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.protocol.optimum import default_folder
from cpp_mujoco.protocol.optimum_cache import OptimumCache


def optimum_figures(grid_map: GridMap, entries: list[dict]) -> dict:
    """Mean coverage of the best missions found and of the bounds, status counts, solve times."""
    targets = int(grid_map.target.sum())
    seen = np.array([e["seen"] for e in entries], dtype=np.float64)
    bound = np.array([e["bound"] for e in entries], dtype=np.float64)
    times = np.array([e["time_s"] for e in entries], dtype=np.float64)
    statuses: dict[str, int] = {}
    for e in entries:
        statuses[e["status"]] = statuses.get(e["status"], 0) + 1
    return {
        "episodes": len(entries),
        "statuses": dict(sorted(statuses.items())),
        "best_found": float(seen.mean() / targets),
        "bound": float(bound.mean() / targets),
        "median_time_s": float(np.median(times)),
        "max_time_s": float(times.max()),
        "solvers": sorted({e["solver"] for e in entries}),
        "time_limits_s": sorted({e["time_limit_s"] for e in entries}),
    }


def optimum_summary(grid_map: GridMap, entries: list[dict], path: Path | None) -> str:
    f = optimum_figures(grid_map, entries)
    counts = ", ".join(f"{n} {s}" for s, n in f["statuses"].items())
    return (
        f"map {grid_map.label} ({grid_map.digest}): {f['episodes']} episodes, {counts}; best "
        f"missions {f['best_found']:.2%} coverage, bound {f['bound']:.2%}; solve time median "
        f"{f['median_time_s']:.1f} s, max {f['max_time_s']:.1f} s ({', '.join(f['solvers'])}, "
        f"limit {', '.join(f'{t:g}' for t in f['time_limits_s'])} s)"
        + (f"; cache {path}" if path else "")
    )


# ----------------------------------------------------- committed results rendered for the docs
def replace_between(text: str, begin: str, end: str, body: str, where: object = "text") -> str:
    """``text`` with what lies between the markers ``begin`` and ``end`` replaced by ``body``."""
    if begin not in text or end not in text:
        raise ValueError(f"{where} lacks the markers {begin} … {end}")
    before, rest = text.split(begin, 1)
    _, after = rest.split(end, 1)
    return f"{before}{begin}\n{body}\n{end}{after}"


def policy_column(policy: str) -> str:
    """A result's policy by what it is: the general agent (``general``, ``ddqn[general]``), a
    per-map agent (``ddqn-A``, ``ddqn[A]``: ``ddqn``), or a planner."""
    if policy in ("general", "ddqn[general]"):
        return "general"
    return "ddqn" if policy.startswith("ddqn") else policy


def optimum_abc_table(data: dict) -> str:
    """The policies against the best missions on maps A, B and C (``results/optimum_abc.json``):
    per map the best missions (proven share, bound), per policy its coverage and its gap to the
    best missions; then each map's cache in a line and the best missions flown in MuJoCo."""
    by_map: dict[str, list[dict]] = {}
    for row in data["results"]:
        by_map.setdefault(row["map"], []).append(row)
    names = list(dict.fromkeys(policy_column(r["policy"]) for r in data["results"]))
    head = ["map", "episodes", "proven optimal", "optimal", "bound"]
    head += [f"{n} (gap)" for n in names]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, rows in by_map.items():
        o = rows[0]["optimum"]
        proven = o["statuses"].get("optimal", 0)
        cells = [
            name, str(rows[0]["episodes"]), f"{proven} / {o['episodes_known']}",
            f"{o['coverage_ratio']:.2%}", f"{o['bound_ratio']:.2%}",
        ]  # fmt: skip
        for row in rows:
            gap = row["optimum"]["gap_to_optimal"] * 100
            cells.append(f"{row['coverage_ratio']:.2%} ({-gap:+.2f})")
        lines.append("| " + " | ".join(cells) + " |")
    policy_names = ", ".join(r["policy"] for r in data["results"][: len(names)])
    lines.append("")
    lines.append(
        f"Grid, full protocol per map ({policy_names}); gap = the policy's coverage minus the "
        "best missions', in points, over the same episodes. Written by "
        "`python scripts/optimum_report.py` from `results/optimum_abc.json`."
    )
    lines.append("")
    lines.extend(proven_share(name) for name in by_map)
    if data.get("physics"):
        lines.append("")
    for row in data.get("physics", []):
        o = row["optimum"]
        budgets = row["conditions"]["budgets"]
        lines.append(
            f"- map {row['map']}, the best missions flown in MuJoCo (calm, budgets "
            f"{budgets['min']}..{budgets['max']} every {budgets['step']}, {row['episodes']} "
            f"episodes): landing {row['landing_ratio']:.2%}, coverage {row['coverage_ratio']:.2%} "
            f"(the grid's best missions {o['coverage_ratio']:.2%}), "
            f"{row['energy_per_action_j']:.0f} J per action, {row['nfz_violations']} no-fly "
            "violations."
        )
    return "\n".join(lines)


def proven_share(name: str) -> str:
    """One map's cache in a line: how many episodes each solver proved at which time limit, how
    many are open and how far, the median and the slowest solve (read from the committed cache,
    so the line is the file's)."""
    entries = OptimumCache(default_folder(), load_map(name)).entries
    proven: dict[str, int] = {}
    for e in entries.values():
        if e["status"] == "optimal":
            by = f"{e['solver']} ({e['time_limit_s']:g} s limit)"
            if "tightened_from" in e:  # a proven entry changes only when its neighbours prove it
                by = (
                    "the episodes beside it (the mission of a smaller budget or of a nearby "
                    "landing cell, the bound of a larger budget or of a nearby landing cell)"
                )
            proven[by] = proven.get(by, 0) + 1
    open_gaps = [e["bound"] - e["seen"] for e in entries.values() if e["status"] != "optimal"]
    times = np.array([e["time_s"] for e in entries.values()])
    slowest = max(  # a proof carried from the episodes beside it took no time of its own
        (e["time_s"], k) for k, e in entries.items()
        if e["status"] == "optimal" and "tightened_from" not in e
    )  # fmt: skip
    row, col, budget = slowest[1].split(",")
    text = f"- map {name}, {len(entries)} episodes: proven " + ", ".join(
        f"{n} by {by}" for by, n in sorted(proven.items(), key=lambda kv: -kv[1])
    )
    if open_gaps:
        text += (f"; not proven {len(open_gaps)} (the best mission {min(open_gaps)}–"
                 f"{max(open_gaps)} targets under the bound)")  # fmt: skip
    return text + (
        f"; solve time median {np.median(times):.1f} s, slowest proven by its solver "
        f"{slowest[0]:.1f} s "
        f"(start ({row}, {col}), {budget} units)."
    )


def optimum_sample_table(data: dict) -> str:
    """The policies against the best missions on a sample of a map set's episodes
    (``results/optimum_<set>.json``, written by ``scripts/optimum_sample.py``)."""
    n = len(data["episodes"])
    proven = data["statuses"].get("optimal", 0)
    lines = [
        "| policy | coverage | gap to the best missions (± standard error) |",
        "|---|---|---|",
        f"| best missions found ({proven} / {n} proven) | {data['best_found']:.2%} | — |",
        f"| proven bound | {data['bound']:.2%} | — |",
    ]
    for name, p in data["policies"].items():
        lines.append(
            f"| {name} | {p['coverage']:.2%} | {p['gap_to_best'] * 100:+.2f} "
            f"± {p['gap_standard_error'] * 100:.2f} pt |"
        )
    lines += [
        "",
        f"{data['map_set']}: {n} episodes drawn uniformly over its protocol (seed "
        f"{data['seed']}), {solved_by(data)}, {data['time_limit_s']:g} s per episode on one core"
        f"{searched(data)}. Written by `python scripts/optimum_sample.py --map-set "
        f"{data['map_set']} --render`.",
    ]
    return "\n".join(lines)


def searched(data: dict) -> str:
    """How long the exact search worked on each question, where it closed open episodes."""
    limit = data.get("search_time_limit_s")
    return f", then the key-target search, {limit:g} s per question" if limit else ""


def solved_by(data: dict) -> str:
    """The solver, or each solver with its share where the episodes were solved by several."""
    solvers = data.get("solvers") or {data["solver"]: len(data["episodes"])}
    if len(solvers) == 1:
        return next(iter(solvers))
    return "solved by " + " and ".join(f"{name} ({n})" for name, n in solvers.items())
