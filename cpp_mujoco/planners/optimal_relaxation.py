"""Missions read off the linear relaxation: its flow peeled into paths, each path a mission.

The relaxation of :class:`~cpp_mujoco.planners.optimal_model.EpisodeModel` spreads its unit of
flow over several walks from the start to a landing cell. Each walk on its own is a mission of the
episode, and the heaviest of them are often better than what a heuristic or the branch and bound
finds in its first minute (map B from (15, 4) with 45 units: a path of the relaxation sees 54
targets; beam search's mission and HiGHS in 60 s, 53). So the solver
(:func:`~cpp_mujoco.planners.optimal_solver.solve_episode`) reads the relaxation first and
starts from its best path.
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.planners.optimal_model import EpisodeModel


def peeled_paths(model: EpisodeModel, x: np.ndarray, max_paths: int = 32) -> list[np.ndarray]:
    """Up to ``max_paths`` walks out of the relaxation's flow ``x``, heaviest first: from the
    start, follow the arc with the most flow left at each layer, then take that walk's smallest
    flow off all its arcs. Each walk is a value of the model's variables (0/1 arcs)."""
    flow = x[: model.tail.size].copy()
    order = np.lexsort((model.tail, model.at))
    keys = model.at[order] * model.g.num_cells + model.tail[order]
    first = np.searchsorted(keys, np.arange(model.moves * model.g.num_cells + 1))
    paths = []
    for _ in range(max_paths):
        cell, chosen = model.start, []
        for t in range(model.moves):
            key = t * model.g.num_cells + cell
            out = order[first[key] : first[key + 1]]
            out = out[flow[out] > 1e-9]
            if out.size == 0:
                break
            arc = int(out[np.argmax(flow[out])])
            chosen.append(arc)
            cell = int(model.head[arc])
        if len(chosen) < model.moves:
            break
        chosen = np.array(chosen)
        flow[chosen] -= flow[chosen].min()
        walk = np.zeros(model.num_vars)
        walk[chosen] = 1.0
        paths.append(walk)
    return paths
