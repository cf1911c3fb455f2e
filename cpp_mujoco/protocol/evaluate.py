"""The paper's evaluation protocol: every landing cell × every budget, greedy policy.

On the grid, episodes run together in a batched :class:`GridMDP` — in chunks of at most
``chunk_cells`` episode-cells, so memory does not grow with episodes × map size; each chunk is one
:func:`~cpp_mujoco.protocol.episode.run_batch` (an episode start for the policy). In MuJoCo the
episodes are flown over this machine's cores or over Ray (:mod:`.physics_engines`). A full
grid protocol for a 16×16 map is one chunk and takes about a second for a fast policy.
Every result carries the map it ran on (``grid_map``) and the conditions that produced its numbers.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np
from tqdm import tqdm

from cpp_mujoco import __version__
from cpp_mujoco.grid.graph import coverage_upper_bound, coverage_upper_bounds
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.map_sets.size_classes import map_size, size_config
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.protocol.episode import OnBatchStep, run_batch
from cpp_mujoco.protocol.optimum import optimum_of, optimum_summary
from cpp_mujoco.protocol.physics_engines import (
    ENGINES,  # what carries MuJoCo episodes
    fly_episodes,
    make_env,
    records_to_arrays,
)
from cpp_mujoco.protocol.policy import Policy, as_policy, check_fits, check_view, policy_identity
from cpp_mujoco.protocol.policy import policy_name as policy_label
from cpp_mujoco.util.io import atomic_write_text, json_default

PAPER_LANDING_RATIO = {"A": 0.9937, "B": 0.9978, "C": 0.9826}
BACKENDS = ("grid", "mujoco")
CHUNK_CELLS = 2**23  # grid protocol: episodes per batch × cells per map stays at most this

__all__ = [
    "BACKENDS",
    "CHUNK_CELLS",
    "ENGINES",
    "PAPER_LANDING_RATIO",
    "EvaluationResult",
    "Policy",  # defined in cpp_mujoco.protocol.policy; importable here as before
    "atomic_write_text",  # from cpp_mujoco.util.io; importable here as before
    "coverage_upper_bound",
    "coverage_upper_bounds",
    "evaluate",
    "protocol_budgets",
    "protocol_episodes",
]


@dataclass
class EvaluationResult:
    """Per-episode outcomes of one protocol run on ``grid_map``; ratios and the per-budget
    table derive; ``conditions``: what else decided the numbers (backend, budgets, options)."""

    grid_map: GridMap
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
    optimum: dict[str, np.ndarray] = field(default_factory=dict)  # per-episode best missions
    conditions: dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:  # the per-episode arrays would bury the figures
        who = f"map {self.map_name} ({self.grid_map.digest}), policy {self.policy_name!r}"
        ratios = f"landing {self.landing_ratio:.2%}, coverage {self.coverage_ratio:.2%}"
        return f"EvaluationResult({who}, {self.backend}, {self.landed.size} episodes: {ratios})"

    @property
    def map_name(self) -> str:
        """The map's label: a user's ``A.png`` is ``A-<digest>``, never the bundled A."""
        return self.grid_map.label

    @property
    def episodes(self) -> int:
        return int(self.landed.size)

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
            row = {
                "budget": int(b),
                "episodes": int(sel.sum()),
                "landing_ratio": float(self.landed[sel].mean()),
                "coverage_ratio": float(self.coverage[sel].mean()),
                "upper_bound": float(self.upper_bound.get(int(b), float("nan"))),
            }
            if self.optimum and (self.optimum["status"][sel] != "").all():  # all known
                row["optimum"] = float(self.optimum["coverage"][sel].mean())
                row["optimum_bound"] = float(self.optimum["bound"][sel].mean())
            rows.append(row)
        return rows

    def summary(self) -> dict[str, object]:
        """Headline figures with the map's identity and the run's conditions."""
        physics = {}
        if self.physics:
            moves = np.maximum(self.steps, 1)
            physics = {
                "energy_per_action_j": float((self.physics["energy_used_j"] / moves).mean()),
                "nfz_violations": int(self.physics["nfz_violations"].sum()),
                "max_track_error_m": float(self.physics["max_track_error_m"].max()),
                "crashes": int(self.physics["crashed"].sum()),
                "mean_flight_time_s": float(self.physics["flight_time_s"].mean()),
            }
        return {
            **self.grid_map.identity(),
            "policy": self.policy_name,
            "backend": self.backend,
            "episodes": int(self.landed.size),
            "landing_ratio": self.landing_ratio,
            "coverage_ratio": self.coverage_ratio,
            "mean_return": float(self.returns.mean()),
            "mean_steps": float(self.steps.mean()),
            **physics,
            **({"optimum": optimum_summary(self.optimum, self.coverage)} if self.optimum else {}),
            "conditions": self.conditions,
        }

    def to_json(self, path: str | os.PathLike) -> None:
        """Write summary and per-budget table atomically."""
        data = {**self.summary(), "per_budget": self.per_budget}
        atomic_write_text(path, json.dumps(data, indent=2, default=json_default))


def protocol_budgets(config: GridConfig | None = None, step: int = 1) -> list[int]:
    """The protocol's budgets: the config's min..max every ``step``, the max always included
    (so a coarse protocol still ends where the full one does)."""
    config = config or GridConfig()
    if step < 1:
        raise ValueError(f"budget step must be >= 1, got {step}")
    return sorted({*range(config.min_budget, config.max_budget + 1, step), config.max_budget})


def protocol_episodes(grid_map: GridMap, budgets: Iterable[int]) -> tuple[np.ndarray, np.ndarray]:
    """Every landing cell × every budget: (starts (E, 2), budgets (E,))."""
    cells = np.argwhere(grid_map.landing)
    budgets = np.asarray(list(budgets), dtype=np.int64)
    return np.repeat(cells, budgets.size, axis=0), np.tile(budgets, len(cells))


def evaluate(
    policy: Policy | Any,
    map: str | os.PathLike | GridMap,  # noqa: A002 - matches the env keyword
    *,
    backend: str = "grid",
    budgets: Iterable[int] | None = None,
    budget_step: int = 1,
    config: GridConfig | None = None,
    policy_name: str | None = None,
    workers: int | None = None,
    progress: bool = False,
    env_kwargs: dict | None = None,
    on_step: OnBatchStep | None = None,
    chunk_cells: int = CHUNK_CELLS,
    engine: str = "local",
    ray_address: str | None = None,
    optimum: str | os.PathLike | None = None,
    any_map: bool = False,
) -> EvaluationResult:
    """Run the full protocol for ``policy`` on ``map``; budgets default to the config's range
    (every ``budget_step``-th, the largest always included), and the config to the map's size
    class (16 → 25..75, 32 → 50..150: :func:`~cpp_mujoco.map_sets.size_classes.size_config`).

    ``policy``: anything with batched ``act`` (optionally ``reset``), an SB3 model (its
    ``predict``, through :class:`~cpp_mujoco.protocol.policy.SB3Policy`) or a plain callable.
    ``backend="mujoco"`` flies every episode in physics, over ``workers`` processes (default:
    all cores) — or, ``engine="ray"``, as Ray tasks on the cluster at ``ray_address`` (else
    ``RAY_ADDRESS``, else a local runtime of ``workers`` CPUs); the numbers are the same on
    either engine (:mod:`cpp_mujoco.protocol.ray_engine`). ``env_kwargs``: :class:`GridConfig`
    fields (either backend) and, for MuJoCo, physics options (``wind_speed=6`` …); an option
    the backend does not know is an error.
    ``on_step(observation, actions, outcome, active)`` (grid only, one chunk) sees every batched
    step — the agent's demonstrations are recorded through it. ``progress``: a tqdm bar.
    A policy that says it does not fit the map (an agent trained on another map) is refused with
    :class:`~cpp_mujoco.protocol.policy.MapMismatchError` unless ``any_map``; then the result's
    conditions say so (``off_its_map``).
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; available: {', '.join(BACKENDS)}")
    if on_step is not None and backend != "grid":
        raise ValueError("on_step is only available with backend='grid'")
    if chunk_cells < 1:
        raise ValueError(f"chunk_cells must be >= 1, got {chunk_cells}")
    _check_engine(backend, engine, ray_address)
    policy = as_policy(policy)
    grid_map = load_map(map)
    off_its_map = check_fits(policy, grid_map, any_map)
    if config is None:  # the map's size class
        config = size_config(map_size(grid_map.shape))
    config, physics_kwargs = _split_options(backend, config, env_kwargs)
    check_view(policy, config.fov_side)
    if budgets is None:
        budgets = protocol_budgets(config, budget_step)
    starts, budget_per_episode = protocol_episodes(grid_map, budgets)
    if budget_per_episode.size == 0:
        raise ValueError("no budgets to evaluate")
    name = policy_name or policy_label(policy)
    bounds = coverage_upper_bounds(grid_map, budget_per_episode, config.fov_side)
    conditions = _conditions(backend, budget_per_episode, config, physics_kwargs)
    if off_its_map:
        conditions["off_its_map"] = off_its_map
    if backend == "mujoco":
        outcome = _run_physics(
            policy, grid_map, starts, budget_per_episode, config, physics_kwargs, workers,
            progress, conditions, engine, ray_address,
        )  # fmt: skip
    else:
        per_chunk = max(1, chunk_cells // grid_map.landing.size)
        conditions["chunk_episodes"] = min(per_chunk, len(starts))
        if on_step is not None and per_chunk < len(starts):
            raise ValueError(
                f"on_step needs the protocol in one batch: {len(starts)} episodes × "
                f"{grid_map.landing.size} cells exceed chunk_cells={chunk_cells}"
            )
        outcome = _run_grid(
            policy, grid_map, starts, budget_per_episode, config, per_chunk, on_step, progress
        )
    if identity := policy_identity(policy):  # after the run: a planner records what it solved
        conditions["policy"] = identity
    best = {} if config.wind is not None else optimum_of(
        grid_map, starts, budget_per_episode, config.fov_side, optimum
    )  # fmt: skip
    return EvaluationResult(
        grid_map=grid_map,
        policy_name=name,
        backend=backend,
        starts=starts,
        budgets=budget_per_episode,
        upper_bound=bounds,
        conditions=conditions,
        optimum=best,
        **outcome,
    )


def _check_engine(backend: str, engine: str, ray_address: str | None) -> None:
    """Ray carries MuJoCo episodes only: the grid protocol is one batch in this process."""
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r}; available: {', '.join(ENGINES)}")
    if engine != "local" and backend != "mujoco":
        raise ValueError(f"engine={engine!r} needs backend='mujoco' (the grid runs here)")
    if ray_address is not None and engine != "ray":
        raise ValueError("ray_address needs engine='ray'")


def _split_options(
    backend: str, config: GridConfig | None, env_kwargs: dict | None
) -> tuple[GridConfig, dict[str, Any]]:
    """(GridConfig with the grid options applied, the remaining options for the physics env)."""
    options = dict(env_kwargs or {})
    if "grid_config" in options:
        raise ValueError("env_kwargs: give the grid config as config=, not env_kwargs")
    grid_names = {f.name for f in fields(GridConfig)}
    grid_kw = {k: options.pop(k) for k in list(options) if k in grid_names}
    try:
        config = GridConfig.from_kwargs(config, **grid_kw)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"env_kwargs: {exc}") from None
    if options and backend == "grid":
        raise ValueError(
            f"env_kwargs {sorted(options)} are not grid options (known: {sorted(grid_names)}); "
            "physics options need backend='mujoco'"
        )
    return config, options


def _conditions(
    backend: str, budgets: np.ndarray, config: GridConfig, env_kwargs: dict
) -> dict[str, Any]:
    """What besides map and policy decided the numbers."""
    values = sorted({int(b) for b in budgets})
    gaps = set(np.diff(values).tolist())
    step = int(gaps.pop()) if len(gaps) == 1 else None
    budget_info: dict[str, Any] = {"min": values[0], "max": values[-1], "step": step}
    if step is None:
        budget_info["values"] = values
    return {
        "backend": backend,
        "episodes": int(budgets.size),
        "budgets": budget_info,
        "fov_side": config.fov_side,
        "grid_config": asdict(config),
        "env_kwargs": dict(env_kwargs),
        "package_version": __version__,
    }


def _run_grid(policy, grid_map, starts, budgets, config, per_chunk, on_step, progress):
    """The grid protocol in chunks of ``per_chunk`` episodes; per-episode arrays as one batch."""
    parts = []
    with tqdm(
        total=len(starts), desc=f"grid {grid_map.label}", unit="ep", disable=not progress
    ) as bar:
        for chunk, lo in enumerate(range(0, len(starts), per_chunk)):
            sl = slice(lo, lo + per_chunk)
            parts.append(
                _run_chunk(policy, grid_map, starts[sl], budgets[sl], config, chunk, on_step, bar)
            )
    length = max(p["trajectories"].shape[1] for p in parts)
    trajectories = np.full((len(starts), length), -1, dtype=np.int64)
    lo = 0
    for p in parts:
        t = p["trajectories"]
        trajectories[lo : lo + len(t), : t.shape[1]] = t
        lo += len(t)
    keys = ("landed", "coverage", "steps", "returns")
    joined = {k: np.concatenate([p[k] for p in parts]) for k in keys}
    return {**joined, "trajectories": trajectories}


def _run_chunk(policy, grid_map, starts, budgets, config, chunk, on_step, bar) -> dict:
    """One batch of protocol episodes (the policy's episode start seeded by ``chunk``)."""
    n = len(starts)
    mdp = GridMDP(grid_map, n, config)
    mdp.reset(np.random.default_rng(0), start=starts, budget=budgets)
    returns = np.zeros(n)
    taken = np.zeros(n, dtype=np.int64)  # actions: in the wind option a unit is not an action
    trail = [mdp.position.copy()]

    def record(obs, actions, out, active) -> None:
        if on_step is not None:
            on_step(obs, actions, out, active)
        returns[:] += out.reward
        taken[:] += active
        trail.append(np.where(active, mdp.position, -1))
        bar.update(int((active & mdp.done).sum()))

    run_batch(mdp, policy, seed=chunk, on_step=record)
    return {
        "landed": mdp.landed.copy(),
        "coverage": mdp.seen_targets / mdp.num_targets,
        "steps": taken,
        "returns": returns,
        "trajectories": np.stack(trail, axis=1),
    }


def _run_physics(
    policy, grid_map, starts, budgets, config, physics_kwargs, workers, progress, conditions,
    engine, ray_address,
) -> dict:  # fmt: skip
    """Fly the protocol in MuJoCo; the env is built here first, so bad options fail at once."""
    env_kwargs = {**physics_kwargs, "grid_config": config}
    env = make_env(grid_map, env_kwargs)
    conditions["physics_config"] = asdict(env.config)
    records = fly_episodes(
        policy, grid_map, starts, budgets, workers, progress, env_kwargs, env, engine, ray_address
    )
    return records_to_arrays(records)


def split_conditions(conditions: list[dict]) -> tuple[dict, list[dict]]:
    """(what every row's conditions share, what each row has of its own), nested dicts split
    key by key — so a sweep's rows carry their wind and nothing else."""
    shared: dict = {}
    own: list[dict] = [{} for _ in conditions]
    missing = object()
    for key in dict.fromkeys(k for c in conditions for k in c):
        values = [c.get(key, missing) for c in conditions]
        if all(v == values[0] for v in values):
            shared[key] = values[0]
        elif all(isinstance(v, dict) for v in values):
            inner_shared, inner_own = split_conditions(values)
            if inner_shared:
                shared[key] = inner_shared
            for row, part in zip(own, inner_own, strict=True):
                if part:
                    row[key] = part
        else:
            for row, v in zip(own, values, strict=True):
                if v is not missing:
                    row[key] = v
    return shared, own
