"""The paper's protocol over a map set: how well a policy does on maps it has never seen.

Each map is flown with the protocol of :func:`~cpp_mujoco.protocol.evaluate.evaluate` (every
landing cell × every budget of the set's size class,
:func:`~cpp_mujoco.map_sets.size_classes.budget_range`) on the grid or in MuJoCo; on the grid the
maps may be flown over worker processes, and a checkpoint lets an interrupted flight resume
(:mod:`~cpp_mujoco.protocol.map_set_rows`). A set's figure for a policy is the mean over its
maps of the per-map ratios, so every map counts the same whatever its landing zone's size; the
ratios pooled over all episodes are recorded beside it. The JSON names the set (name, version,
how many of its maps), every map (name, seed, digest), the policy, backend and budgets, so no
number is ambiguous. Each row also keeps one example episode (the map's first landing cell, the
middle budget: its cells, coverage, landing), so the figures
(:mod:`cpp_mujoco.review.map_set_figures`) can show what a policy did on a map from the JSON
alone, without flying it again.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.grid.wind import GridWind
from cpp_mujoco.map_sets.sets import MapSetSpec
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.maps import GridMap
from cpp_mujoco.protocol.evaluate import protocol_budgets, split_conditions
from cpp_mujoco.protocol.map_set_rows import RowTask, example_budget, fly_rows
from cpp_mujoco.protocol.physics_tasks import make_env
from cpp_mujoco.util.io import atomic_write_text, json_default, json_plain
from cpp_mujoco.util.tables import format_table


@dataclass
class MapSetResult:
    """Per-map, per-policy protocol figures over a list of maps: a held-out set (or its first
    maps), or a training run's validation pool. The first policy is the result's subject (its
    ``landing_ratio`` …); the others are flown beside it on the same maps and budgets."""

    identity: dict  # what the maps are: a set's name, version, size … or a pool's seeds and digest
    maps: list[GridMap]
    budgets: dict[int, list[int]]  # the budgets flown, per map side (its size class's)
    budget_step: int
    rows: list[dict] = field(default_factory=list)  # one per map and policy
    backend: str = "grid"
    conditions: dict = field(default_factory=dict)  # the run's own (e.g. a training run's)

    def __repr__(self) -> str:  # the maps and rows would bury the figures
        means = ", ".join(
            f"{s['policy']}: landing {s['mean_landing_ratio']:.2%}, coverage "
            f"{s['mean_coverage_ratio']:.2%}"
            for s in self.summary()
        )
        return f"MapSetResult({self.name}, {len(self.maps)} maps, {self.backend}; {means})"

    @property
    def name(self) -> str:
        return str(self.identity.get("name", "maps"))

    def _subject(self) -> dict:
        if not self.rows:
            raise ValueError(f"{self.name}: no policy flown yet")
        return self.summary()[0]

    @property
    def landing_ratio(self) -> float:
        """The first policy's landing ratio, the mean over the maps."""
        return self._subject()["mean_landing_ratio"]

    @property
    def coverage_ratio(self) -> float:
        """The first policy's coverage ratio, the mean over the maps."""
        return self._subject()["mean_coverage_ratio"]

    @property
    def episodes(self) -> int:
        return self._subject()["episodes"]

    @property
    def returns(self) -> np.ndarray:
        """The first policy's mean return per map (``returns.mean()`` weighs the maps equally)."""
        first = self.policies[0]
        return np.array([r["mean_return"] for r in self.rows if r["policy"] == first])

    def extend(self, other: MapSetResult) -> None:
        """Add the rows of ``other``: more policies flown on the same maps and budgets."""
        same = [m.digest for m in self.maps] == [m.digest for m in other.maps]
        if not same or self.budgets != other.budgets or self.backend != other.backend:
            raise ValueError(f"{other.name}: not the maps, budgets and backend of {self.name}")
        self.rows.extend(other.rows)

    @property
    def policies(self) -> list[str]:
        return list(dict.fromkeys(r["policy"] for r in self.rows))

    def summary(self) -> list[dict]:
        """One row per policy: the means over the maps, the pooled ratios, the wall time."""
        out = []
        for name in self.policies:
            rows = [r for r in self.rows if r["policy"] == name]
            episodes = np.array([r["episodes"] for r in rows])
            landing = np.array([r["landing_ratio"] for r in rows])
            coverage = np.array([r["coverage_ratio"] for r in rows])
            out.append(
                {
                    "policy": name,
                    "maps": len(rows),
                    "episodes": int(episodes.sum()),
                    "mean_landing_ratio": float(landing.mean()),
                    "mean_coverage_ratio": float(coverage.mean()),
                    "min_landing_ratio": float(landing.min()),
                    "pooled_landing_ratio": float((landing * episodes).sum() / episodes.sum()),
                    "pooled_coverage_ratio": float((coverage * episodes).sum() / episodes.sum()),
                    "seconds": float(sum(r["seconds"] for r in rows)),
                }
            )
            if len(self.budgets) > 1:  # several size classes: each one's means too
                side = np.array([max(m.shape) for m in self.maps])
                out[-1]["per_size"] = {
                    str(size): {
                        "maps": int((side == size).sum()),
                        "mean_landing_ratio": float(landing[side == size].mean()),
                        "mean_coverage_ratio": float(coverage[side == size].mean()),
                    }
                    for size in sorted(self.budgets)
                }
        return out

    def to_dict(self) -> dict:
        """The set, the budgets, the conditions every row shares once, the per-policy means, and
        the rows (map name, seed, digest, policy, numbers, and their own conditions)."""
        shared, own = split_conditions([json_plain(r["conditions"]) for r in self.rows])
        rows = []
        for row, conditions in zip(self.rows, own, strict=True):
            entry = json_plain({k: v for k, v in row.items() if k != "conditions"})
            if conditions:
                entry["conditions"] = conditions
            rows.append(entry)

        def per_side(value):  # one size class: the value; several: the value per side
            out = {str(side): value(b) for side, b in sorted(self.budgets.items())}
            return next(iter(out.values())) if len(out) == 1 else out

        return {
            "map_set": self.identity,
            "backend": self.backend,
            "budgets": per_side(lambda b: {"min": b[0], "max": b[-1], "step": self.budget_step}),
            "mean_is": "the mean over the maps of each map's ratio (every map weighs the same)",
            "example_episode": {
                "start": "each map's first landing cell (row-major order)",
                "budget": per_side(example_budget),
            },
            "policies": self.summary(),
            "conditions": {**shared, **json_plain(self.conditions)},
            "rows": rows,
        }

    def to_json(self, path: str | Path) -> Path:
        atomic_write_text(path, json.dumps(self.to_dict(), indent=2, default=json_default))
        return Path(path)

    def tables(self) -> tuple[str, str]:
        """(per map: each policy's landing and coverage; per policy: the means over the set)."""
        names = self.policies
        per_map: dict[str, dict] = {}
        for r in self.rows:
            row = per_map.setdefault(
                r["map"], {"map": r["map"], "digest": r["map_digest"], "landing cells": 0}
            )
            row["landing cells"] = r["landing_cells"]
            row[f"{r['policy']} landing"] = f"{r['landing_ratio']:.2%}"
            row[f"{r['policy']} coverage"] = f"{r['coverage_ratio']:.2%}"
        mean = {"map": f"mean of {len(self.maps)}", "digest": "", "landing cells": ""}
        for s in self.summary():
            mean[f"{s['policy']} landing"] = f"{s['mean_landing_ratio']:.2%}"
            mean[f"{s['policy']} coverage"] = f"{s['mean_coverage_ratio']:.2%}"
        columns = ["map", "digest", "landing cells"]
        columns += [f"{n} {what}" for n in names for what in ("landing", "coverage")]
        means = [
            {
                "policy": s["policy"],
                "maps": s["maps"],
                "episodes": s["episodes"],
                "mean landing": f"{s['mean_landing_ratio']:.2%}",
                "mean coverage": f"{s['mean_coverage_ratio']:.2%}",
                "worst map landing": f"{s['min_landing_ratio']:.2%}",
                "seconds": f"{s['seconds']:.1f}",
            }
            for s in self.summary()
        ]
        mean_columns = ["policy", "maps", "episodes", "mean landing", "mean coverage"]
        return (
            format_table([*per_map.values(), mean], columns),
            format_table(means, [*mean_columns, "worst map landing", "seconds"]),
        )


def check_physics(spec: MapSetSpec, grid_map: GridMap, env_kwargs: dict | None = None) -> None:
    """Build the MuJoCo env of the set's first map before anything flies, so a set the physics
    cannot hold (or a bad weather option) fails at once, naming the set and its size."""
    try:
        env = make_env(grid_map, {**(env_kwargs or {}), "grid_config": size_config(spec.size)})
    except ValueError as e:
        text = " ".join(str(e).split())
        raise ValueError(
            f"map set {spec.name!r} ({spec.size}x{spec.size}) cannot be flown in MuJoCo: "
            f"map {grid_map.label}: {text}"
        ) from e
    env.close()


def evaluate_map_set(
    spec: MapSetSpec,
    maps: Sequence[GridMap],
    policies: Sequence[tuple[str, Any]],
    budget_step: int = 1,
    progress: bool = False,
    backend: str = "grid",
    *,
    workers: int | None = None,
    env_kwargs: dict | None = None,
    engine: str = "local",
    grid_wind: GridWind | None = None,
    checkpoint: str | Path | None = None,
) -> MapSetResult:
    """Every policy over every map of the set on ``backend``, with the set's size-class budgets
    (every ``budget_step``-th, the maximum always included). ``workers``: in MuJoCo the episode
    workers of :func:`~cpp_mujoco.protocol.evaluate.evaluate` (with its ``env_kwargs``, the
    weather, and ``engine``); on the grid, processes flying maps side by side (default: here).
    ``grid_wind``: on the grid, the wind option every episode draws its wind from (each row's
    conditions record it). ``checkpoint``: a file keeping each row as it lands, so the flight
    resumes (:mod:`~cpp_mujoco.protocol.map_set_rows`)."""
    if not maps:
        raise ValueError(f"map set {spec.name!r}: no maps to evaluate")
    if len(maps) > spec.count:
        raise ValueError(f"map set {spec.name!r} has {spec.count} maps, got {len(maps)}")
    for grid_map, digest in zip(maps, spec.digests, strict=False):
        if grid_map.digest != digest:  # rows name each map by the set's seed: they must match
            raise ValueError(f"map {grid_map.label!r} is not the next map of set {spec.name!r}")
    if backend == "mujoco":
        check_physics(spec, maps[0], env_kwargs)
    config = size_config(spec.size)
    if grid_wind is not None:
        if backend != "grid":
            raise ValueError("grid_wind is the grid's wind option; MuJoCo flies env_kwargs' wind")
        config = replace(config, wind=grid_wind)
    mujoco = backend == "mujoco"
    physics = {"workers": workers, "env_kwargs": env_kwargs, "engine": engine} if mujoco else None
    return evaluate_maps(
        spec.identity(len(maps)), maps, [config] * len(maps), spec.seeds[: len(maps)], policies,
        budget_step, progress, backend, physics,
        map_workers=None if mujoco else workers, checkpoint=checkpoint,
    )  # fmt: skip


def evaluate_maps(identity: dict, maps: Sequence[GridMap], configs: Sequence[GridConfig],
                  seeds: Sequence[int], policies: Sequence[tuple[str, Any]], budget_step: int = 1,
                  progress: bool = False, backend: str = "grid",
                  physics: dict[str, Any] | None = None, *, map_workers: int | None = None,
                  checkpoint: str | Path | None = None) -> MapSetResult:  # fmt: skip
    """Every policy over every map with the map's own config (its size class's budgets, every
    ``budget_step``-th): the protocol of :func:`evaluate_map_set` for any list of maps, e.g. a
    training run's validation pool; ``identity`` says what the maps are, ``seeds`` name them;
    ``physics``: :func:`~cpp_mujoco.protocol.evaluate.evaluate`'s MuJoCo options (``workers``,
    ``env_kwargs``, ``engine``); ``map_workers`` and ``checkpoint``:
    :func:`~cpp_mujoco.protocol.map_set_rows.fly_rows`'s."""
    physics = physics or {}
    budgets: dict[int, list[int]] = {}
    for grid_map, config in zip(maps, configs, strict=True):
        flown = protocol_budgets(config, step=budget_step)
        if budgets.setdefault(max(grid_map.shape), flown) != flown:
            raise ValueError(f"maps of side {max(grid_map.shape)} with different budgets")
    result = MapSetResult(identity, list(maps), budgets, budget_step, backend=backend)
    tasks = [
        RowTask(name, policy, grid_map, seed, config, budgets[max(grid_map.shape)], backend,
                physics)
        for name, policy in policies
        for grid_map, seed, config in zip(maps, seeds, configs, strict=True)
    ]  # fmt: skip
    with tqdm(total=len(tasks), desc=result.name, unit="run", disable=not progress) as bar:
        result.rows = fly_rows(tasks, map_workers, checkpoint, on_row=bar.update)
    return result
