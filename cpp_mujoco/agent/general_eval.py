"""Greedy evaluation of a policy on a pool's maps: the general agent's validation.

Each map is flown with the paper's protocol (every landing cell × every ``budget_step``-th
budget of its size class, :func:`~cpp_mujoco.protocol.evaluate.evaluate`) and the figures are means
over
the maps, so every map weighs the same whatever its size or landing zone — as for the held-out
map sets (:mod:`cpp_mujoco.protocol.map_sets`), which stay the final test.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cpp_mujoco.agent.map_pool import MapPool
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets
from cpp_mujoco.util.io import atomic_write_text, json_default


@dataclass
class ValidationResult:
    """Per-map protocol figures of one policy; headline ratios are means over the maps."""

    rows: list[dict]  # one per map: label, seed, size, digest, episodes, ratios, mean return
    landed: np.ndarray  # every episode's landing flag (all maps)
    budget_step: int
    references: dict[str, dict] = field(default_factory=dict)  # planner → its summary
    conditions: dict = field(default_factory=dict)

    @property
    def landing_ratio(self) -> float:
        return float(np.mean([r["landing_ratio"] for r in self.rows]))

    @property
    def coverage_ratio(self) -> float:
        return float(np.mean([r["coverage_ratio"] for r in self.rows]))

    @property
    def returns(self) -> np.ndarray:
        """Each map's mean return (so ``returns.mean()`` weighs the maps equally)."""
        return np.array([r["mean_return"] for r in self.rows])

    def summary(self) -> dict:
        per_size = {}
        for size in sorted({r["size"] for r in self.rows}):
            rows = [r for r in self.rows if r["size"] == size]
            per_size[str(size)] = {
                "maps": len(rows),
                "landing_ratio": float(np.mean([r["landing_ratio"] for r in rows])),
                "coverage_ratio": float(np.mean([r["coverage_ratio"] for r in rows])),
            }
        return {
            "maps": len(self.rows),
            "episodes": int(self.landed.size),
            "budget_step": self.budget_step,
            "landing_ratio": self.landing_ratio,
            "coverage_ratio": self.coverage_ratio,
            "mean_return": float(self.returns.mean()),
            "per_size": per_size,
        }

    def to_json(self, path: str | os.PathLike) -> Path:
        data = {
            "mean_is": "the mean over the maps of each map's ratio (every map weighs the same)",
            **self.summary(),
            "references": self.references,
            "conditions": self.conditions,
            "rows": self.rows,
        }
        atomic_write_text(path, json.dumps(data, indent=2, default=json_default))
        return Path(path)


def validate(policy, pool: MapPool, budget_step: int = 1) -> ValidationResult:
    """``policy`` over every map of ``pool`` (its size class's budgets, every ``budget_step``)."""
    rows, landed = [], []
    for grid_map, seed, config in zip(pool.maps, pool.seeds, pool.configs, strict=True):
        res = evaluate(
            policy, grid_map, budgets=protocol_budgets(config, budget_step), config=config
        )
        landed.append(res.landed)
        rows.append(
            {
                "map": grid_map.label,
                "seed": seed,
                "size": max(grid_map.shape),
                "digest": grid_map.digest,
                "episodes": int(res.landed.size),
                "landing_ratio": res.landing_ratio,
                "coverage_ratio": res.coverage_ratio,
                "mean_return": float(res.returns.mean()),
            }
        )
    return ValidationResult(rows, np.concatenate(landed), budget_step)
