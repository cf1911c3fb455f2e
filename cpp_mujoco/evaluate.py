"""The paper's evaluation protocol (DESIGN §7): every landing cell × every budget, greedy policy.

All episodes of a protocol run at once in one batched :class:`GridMDP`, so a full protocol for a
16×16 map takes about a second for a fast policy.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from cpp_mujoco.grid.mdp import GridConfig, GridMDP, StepOutcome
from cpp_mujoco.maps import GridMap, load_map

PAPER_LANDING_RATIO = {"A": 0.9937, "B": 0.9978, "C": 0.9826}
BACKENDS = ("grid", "mujoco")


class Policy(Protocol):
    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Actions (N,) for a batch of observations with leading dimension N."""


@dataclass
class EvaluationResult:
    """Per-episode outcomes of one protocol run; ratios and the per-budget table derive."""

    map_name: str
    policy_name: str
    backend: str
    starts: np.ndarray  # (E, 2) row, col
    budgets: np.ndarray  # (E,)
    landed: np.ndarray  # (E,) bool
    coverage: np.ndarray  # (E,) coverage ratio at the end
    steps: np.ndarray  # (E,) actions taken
    returns: np.ndarray  # (E,) undiscounted return
    trajectories: np.ndarray  # (E, T+1) flat cells visited, -1 after the end
    upper_bound: dict[int, float] = field(default_factory=dict)  # budget → coverage bound
    physics: dict[str, np.ndarray] = field(default_factory=dict)  # per-episode physical figures

    @property
    def landing_ratio(self) -> float:
        return float(self.landed.mean())

    @property
    def coverage_ratio(self) -> float:
        return float(self.coverage.mean())

    @property
    def per_budget(self) -> list[dict[str, float]]:
        """One row per budget: episodes, landing ratio, mean coverage, and the coverage bound."""
        rows = []
        for b in np.unique(self.budgets):
            sel = self.budgets == b
            rows.append(
                {
                    "budget": int(b),
                    "episodes": int(sel.sum()),
                    "landing_ratio": float(self.landed[sel].mean()),
                    "coverage_ratio": float(self.coverage[sel].mean()),
                    "upper_bound": float(self.upper_bound.get(int(b), float("nan"))),
                }
            )
        return rows

    def summary(self) -> dict[str, object]:
        physics = {}
        if self.physics:
            moves = np.maximum(self.steps, 1)
            physics = {
                "energy_per_action_j": float((self.physics["energy_used_j"] / moves).mean()),
                "nfz_violations": int(self.physics["nfz_violations"].sum()),
                "crashes": int(self.physics["crashed"].sum()),
                "mean_flight_time_s": float(self.physics["flight_time_s"].mean()),
            }
        return {
            "map": self.map_name,
            "policy": self.policy_name,
            "backend": self.backend,
            "episodes": int(self.landed.size),
            "landing_ratio": self.landing_ratio,
            "coverage_ratio": self.coverage_ratio,
            "mean_return": float(self.returns.mean()),
            "mean_steps": float(self.steps.mean()),
            **physics,
        }

    def to_json(self, path: str | os.PathLike) -> None:
        """Write summary and per-budget table atomically."""
        atomic_write_text(
            path, json.dumps({**self.summary(), "per_budget": self.per_budget}, indent=2)
        )


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    tmp = f"{os.fspath(path)}.tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def coverage_upper_bound(grid_map: GridMap, budget: int, fov_side: int = 3) -> float:
    """An upper bound on the coverage ratio any policy reaches with ``budget`` actions."""
    return coverage_upper_bounds(grid_map, [budget], fov_side)[budget]


def coverage_upper_bounds(
    grid_map: GridMap, budgets: Iterable[int], fov_side: int = 3
) -> dict[int, float]:
    """Budget → an upper bound on the coverage ratio any policy reaches with that many actions.

    min(targets visible from cells it can visit and still land, cells a path can see) / targets.
    A visited cell c needs ``2·d(c) + 1 <= budget`` (out from a landing cell, back, land), with
    d the flight distance to the landing zone; the path sees at most ``fov_side²`` cells at its
    first step and ``fov_side`` new cells per further move (one action is the landing).
    """
    from cpp_mujoco.planners.graph import build_graph

    g = build_graph(grid_map, fov_side)  # one all-pairs distance table for every budget
    bounds = {}
    for budget in {int(b) for b in budgets}:
        visitable = 2 * (g.home - 1) + 1 <= budget
        visible = int(g.fov_targets[visitable].any(axis=0).sum())
        seeable = fov_side**2 + fov_side * max(budget - 2, 0)
        bounds[budget] = float(min(visible, seeable) / grid_map.target.sum())
    return bounds


def protocol_episodes(grid_map: GridMap, budgets: Iterable[int]) -> tuple[np.ndarray, np.ndarray]:
    """Every landing cell × every budget: (starts (E, 2), budgets (E,))."""
    cells = np.argwhere(grid_map.landing)
    budgets = np.asarray(list(budgets), dtype=np.int64)
    return np.repeat(cells, budgets.size, axis=0), np.tile(budgets, len(cells))


def evaluate(
    policy: Policy,
    map: str | os.PathLike | GridMap,  # noqa: A002 - matches the env keyword
    *,
    backend: str = "grid",
    budgets: Iterable[int] | None = None,
    config: GridConfig | None = None,
    policy_name: str | None = None,
    workers: int | None = None,
    progress: bool = False,
    env_kwargs: dict | None = None,
    on_step: Callable[[dict, np.ndarray, StepOutcome, np.ndarray], None] | None = None,
) -> EvaluationResult:
    """Run the full protocol for ``policy`` on ``map``; budgets default to the config's range.

    ``backend="mujoco"`` flies every episode in physics, over ``workers`` processes (default:
    all cores), with ``env_kwargs`` for the physics env (``wind_speed=6`` …).
    ``on_step(observation, actions, outcome, active)`` (grid only) sees every batched step — the
    agent's demonstrations are recorded through it.
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; available: {', '.join(BACKENDS)}")
    if on_step is not None and backend != "grid":
        raise ValueError("on_step is only available with backend='grid'")
    grid_map = load_map(map)
    config = config or GridConfig()
    if budgets is None:
        budgets = range(config.min_budget, config.max_budget + 1)
    starts, budget_per_episode = protocol_episodes(grid_map, budgets)
    name = policy_name or getattr(policy, "name", type(policy).__name__)
    bounds = coverage_upper_bounds(grid_map, budget_per_episode, config.fov_side)
    if backend == "mujoco":
        return _evaluate_physics(
            policy, grid_map, starts, budget_per_episode, name, bounds, workers, progress,
            {**(env_kwargs or {}), "fov_side": config.fov_side},
        )  # fmt: skip
    mdp = GridMDP(grid_map, len(starts), config)
    mdp.reset(np.random.default_rng(0), start=starts, budget=budget_per_episode)
    returns = np.zeros(len(starts))
    trail = [mdp.position.copy()]
    while not mdp.done.all():
        active = ~mdp.done
        obs = mdp.observation()
        actions = np.asarray(policy.act(obs), dtype=np.int64).reshape(-1)
        out = mdp.step(actions, active=active)
        if on_step is not None:
            on_step(obs, actions, out, active)
        returns += out.reward
        trail.append(np.where(active, mdp.position, -1))
    return EvaluationResult(
        map_name=grid_map.name,
        policy_name=name,
        backend=backend,
        starts=starts,
        budgets=budget_per_episode,
        landed=mdp.landed.copy(),
        coverage=mdp.seen_targets / mdp.num_targets,
        steps=mdp.steps.copy(),
        returns=returns,
        trajectories=np.stack(trail, axis=1),
        upper_bound=bounds,
    )


def _evaluate_physics(
    policy, grid_map, starts, budgets, name, bounds, workers, progress, env_kwargs
):
    from cpp_mujoco.physics.episodes import fly_episodes

    records = fly_episodes(policy, grid_map, starts, budgets, workers, progress, env_kwargs)
    length = max(len(r.cells) for r in records)
    trajectories = np.full((len(records), length), -1, dtype=np.int64)
    for i, r in enumerate(records):
        trajectories[i, : len(r.cells)] = r.cells

    def column(key: str, dtype=float) -> np.ndarray:
        return np.array([getattr(r, key) for r in records], dtype=dtype)

    return EvaluationResult(
        map_name=grid_map.name,
        policy_name=name,
        backend="mujoco",
        starts=starts,
        budgets=budgets,
        landed=column("landed", bool),
        coverage=column("coverage"),
        steps=column("steps", np.int64),
        returns=column("total_reward"),
        trajectories=trajectories,
        upper_bound=bounds,
        physics={
            "energy_used_j": column("energy_used_j"),
            "flight_time_s": column("flight_time_s"),
            "nfz_violations": column("nfz_violations", np.int64),
            "crashed": column("crashed", bool),
            "crash_reason": np.array([r.crash_reason or "" for r in records]),
        },
    )
