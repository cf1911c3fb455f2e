"""The line-up a map is compared with, and the run that flies it into tables and figures.

:func:`demo_policies` and :func:`wind_variants` name the policies of the demo, the transfer and
wind tables; :func:`run_evaluation` flies each policy through the protocol and writes its JSON,
figures and the table (:mod:`~cpp_mujoco.review.results` builds the rows).
"""

from __future__ import annotations

import time
from pathlib import Path

from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.planners import SafeGreedyPlanner, WindSafeGreedyPlanner
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.review.plots import coverage_figure, trajectories_figure
from cpp_mujoco.review.results import PROTOCOL_COLUMNS, Table, file_part, protocol_row, write_tables


def demo_policies(map: str | GridMap) -> list[tuple[str, object]]:  # noqa: A002
    """The policies the demo and the transfer tables compare: a bundled map's bundled agent
    (where there is one) and its wind-robust agent (``A-wind``, where there is one), then the
    safe greedy planner."""
    from cpp_mujoco.agent import bundled_agents, load_agent  # heavy: torch, off the planners' runs

    grid_map = load_map(map)
    policies: list[tuple[str, object]] = []
    if grid_map.bundled and grid_map.name in bundled_agents():
        policies.append((f"ddqn[{grid_map.name}]", load_agent(grid_map.name)))
    if grid_map.bundled and f"{grid_map.name}-wind" in bundled_agents():
        policies.append((f"ddqn-wind[{grid_map.name}]", load_agent(f"{grid_map.name}-wind")))
    policies.append(("safe-greedy", SafeGreedyPlanner()))
    return policies


def wind_variants(map: str | GridMap, guard: bool = True) -> list[tuple[str, object, bool]]:  # noqa: A002
    """(name, policy, return guard on) compared in wind: the demo policies, the safe greedy
    planner that prices moves with the wind (``safe-greedy-wind``, the wind agents' guide), and
    with ``guard`` the paper agent and the planner again flown with the return guard
    (``name + guard``); a wind-robust agent flies as it is meant to, unguarded."""
    policies = demo_policies(map)
    out = [(name, policy, False) for name, policy in policies]
    out.append(("safe-greedy-wind", WindSafeGreedyPlanner(), False))
    if guard:
        out += [(f"{n} + guard", p, True) for n, p in policies if not n.startswith("ddqn-wind")]
    return out


def select_wind_variants(grid_maps, names=None, guard: bool = True) -> dict[str, list]:
    """:func:`wind_variants` of each map (by label), only those ``names`` picks (None: all);
    ``ValueError`` naming a name no map has, before anything is flown."""
    variants = {g.label: wind_variants(g, guard) for g in grid_maps}
    known = {name for vs in variants.values() for name, _, _ in vs}
    unknown = sorted(set(names or ()) - known)
    if unknown:
        raise ValueError(f"unknown policies {unknown}; on these maps: {sorted(known)}")
    return {label: [v for v in vs if not names or v[0] in names] for label, vs in variants.items()}


# ------------------------------------------------------------------------------- row builders


def run_evaluation(
    maps, policies, out: Path, backend: str = "grid", verbose: bool = True, **evaluate_kwargs
) -> dict[str, list]:
    """Evaluate every policy on every map; write JSON, figures and the table; print the table.

    ``maps``: names, paths or :class:`GridMap` objects, each loaded once and passed on as the
    map object, so results and file names carry the map actually evaluated (its label).
    ``policies``: (name, policy) pairs, or a callable GridMap → pairs. Writes per policy
    ``{backend}_{map}_{policy}.json`` and a trajectories figure, per map a coverage figure, and
    the table as ``{backend}_tables.json``. Returns map label → results.
    """
    grid_maps = [load_map(m) for m in maps]
    table = Table(f"the paper's protocol ({backend})", PROTOCOL_COLUMNS)
    results: dict[str, list] = {}
    for grid_map in grid_maps:
        label, per_map = file_part(grid_map.label), []
        chosen = policies(grid_map) if callable(policies) else policies
        for name, policy in chosen:
            start = time.perf_counter()
            result = evaluate(
                policy, grid_map, backend=backend, policy_name=name, **evaluate_kwargs
            )
            seconds = time.perf_counter() - start
            stem = f"{backend}_{label}_{file_part(name)}"
            result.to_json(out / f"{stem}.json")
            per_map.append(result)
            table.rows.append(protocol_row(result, seconds))
            trajectories_figure(result, out / f"{stem}_trajectories.png")
        coverage_figure(per_map, out / f"{backend}_{label}_coverage.png")
        results[grid_map.label] = per_map
    write_tables(out / f"{backend}_tables.json", {"protocol": table})
    if verbose:
        print(table.render())
    return results
