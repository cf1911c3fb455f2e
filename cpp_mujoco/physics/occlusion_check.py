"""Physics vs grid coverage on maps with obstacles: where 3-D rays and cell lines disagree.

The grid decides what the camera sees past an obstacle with a line between cell centres
(:mod:`cpp_mujoco.grid.occlusion`); the physics camera casts a ray from where the camera really
is to each cell centre on the ground and meets the obstacles' boxes at their heights
(:mod:`cpp_mujoco.physics.sensing.occlusion`). :func:`compare_coverage` flies each episode with a
policy on the grid, flies the very same actions in MuJoCo, and lists the target cells one counts
and the other does not. Replaying the grid's actions (rather than letting the policy decide
again from the physics' coverage) keeps the two routes identical, so every difference is the
sensing's (or a physical failure, which the result names). One convention is set aside: the grid
marks the view of each cell it moves to, the physics camera also takes a frame before the first
move; the grid's view from the start cell (its own rule) is counted as the grid's too.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cpp_mujoco.grid.coverage import view_cells
from cpp_mujoco.grid.env import GridEnv
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.envs.single import MuJoCoEnv

Cell = tuple[int, int]


@dataclass
class CoverageGap:
    """One episode flown on both backends: the grid's actions, the target cells each counted,
    and those only one of them did (``extra``: the physics only, ``missing``: the grid only)."""

    start: Cell
    budget: int
    actions: list[int]
    grid_seen: int  # target cells the grid counted, with its view from the start
    physics_seen: int  # target cells the physics camera counted
    extra: list[Cell]
    missing: list[Cell]
    physics_steps: int  # actions the physics flew (fewer than the grid's after a failure)
    crash_reason: str | None  # the physics episode's, None if it landed

    @property
    def extra_share(self) -> float:
        """Cells only the physics counted, as a share of the grid's seen target cells."""
        return len(self.extra) / self.grid_seen if self.grid_seen else 0.0

    @property
    def missing_share(self) -> float:
        """Cells only the grid counted, as a share of the grid's seen target cells."""
        return len(self.missing) / self.grid_seen if self.grid_seen else 0.0


def _act(policy: Any, obs: dict[str, np.ndarray]) -> int:
    """The batched ``act`` of the policy protocol for one observation."""
    actions = np.asarray(policy.act({k: np.asarray(v)[None] for k, v in obs.items()}))
    return int(actions.reshape(-1)[0])


def compare_coverage(
    grid_map: GridMap,
    starts: list[Cell],
    budgets: list[int],
    policy: Any,
    config: PhysicsConfig | None = None,
    seed: int = 0,
    fov_side: int = 3,
) -> list[CoverageGap]:
    """Episode k starts at ``starts[k]`` with ``budgets[k]`` units: ``policy`` (anything with a
    batched ``act``, e.g. ``cpp_mujoco.planners.make_planner("safe-greedy")``) flies it on the
    grid, MuJoCo flies the same actions (``config``, calm air by default), and the target cells
    each backend counted are compared. Both envs are reset with ``seed``."""
    if len(starts) != len(budgets):
        raise ValueError(f"{len(starts)} starts but {len(budgets)} budgets")
    config = config or PhysicsConfig()
    grid = GridEnv(grid_map, fov_side=fov_side)
    physics = MuJoCoEnv(grid_map, config, fov_side=fov_side)
    target = grid_map.target.reshape(-1)
    width = grid_map.shape[1]
    view, in_view = view_cells(grid_map, fov_side)
    gaps = []
    try:
        for start, budget in zip(starts, budgets, strict=True):
            options = {"start": tuple(start), "budget": int(budget)}
            reset = getattr(policy, "reset", None)
            if callable(reset):
                reset(1, seed)
            obs, _ = grid.reset(seed=seed, options=options)
            actions, done = [], False
            while not done:
                actions.append(_act(policy, obs))
                obs, _, terminated, truncated, _ = grid.step(actions[-1])
                done = terminated or truncated
            physics.reset(seed=seed, options=options)
            steps, info = 0, {}
            for action in actions:
                _, _, terminated, truncated, info = physics.step(action)
                steps += 1
                if terminated or truncated:
                    break
            seen_grid = grid.mdp.coverage[0].copy()
            first = start[0] * width + start[1]
            seen_grid[view[first][in_view[first]]] = True  # the physics' frame at the start
            seen_grid &= target
            seen_physics = physics.mdp.coverage[0] & target

            def cells(mask: np.ndarray) -> list[Cell]:
                return [divmod(int(c), width) for c in np.flatnonzero(mask)]

            gaps.append(CoverageGap(
                tuple(start), int(budget), actions, int(seen_grid.sum()),
                int(seen_physics.sum()), cells(seen_physics & ~seen_grid),
                cells(seen_grid & ~seen_physics), steps, info.get("crash_reason"),
            ))  # fmt: skip
    finally:
        grid.close()
        physics.close()
    return gaps
