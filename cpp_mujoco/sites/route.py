"""One episode on a site's map, flown in MuJoCo: the policy's route, and the same route again
from its waypoints.

A policy (planner, agent, exact planner) flies the episode through the protocol's own loop
(:func:`~cpp_mujoco.protocol.episode.run_episode` on ``MuJoCo-v0``), so the route is what the
physics flew: the cells the drone was over, the energy it drew from the pack, the cells its
camera saw. A waypoint file is flown back through :class:`ActionReplay`: the moves between the
cells its waypoints name, then the landing — the actions come from the file, not the policy.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.grid.actions import LAND, MOVES
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.protocol.episode import run_episode
from cpp_mujoco.protocol.policy import check_fits, policy_name

Cell = tuple[int, int]


@dataclass
class FlownRoute:
    """One episode flown in MuJoCo: where the drone went and what it cost."""

    policy: str
    start: Cell
    budget: int
    cells: list[Cell]  # the cells it was over, the start first, a hover not repeated
    actions: list[int]  # what the policy chose, the landing last
    landed: bool
    crash_reason: str | None
    coverage_ratio: float
    seen: np.ndarray = field(repr=False)  # (H, W) bool: target cells the camera saw
    energy_used_j: float = 0.0  # J drawn from the pack, the landing included
    flight_time_s: float = 0.0
    nfz_violations: int = 0

    @property
    def end(self) -> Cell:
        return self.cells[-1]

    def summary(self) -> dict[str, Any]:
        return {
            "policy": self.policy,
            "start": list(self.start),
            "budget": self.budget,
            "actions": len(self.actions),
            "waypoints": len(self.cells),
            "landed": self.landed,
            "crash_reason": self.crash_reason,
            "coverage_ratio": self.coverage_ratio,
            "targets_seen": int(self.seen.sum()),
            "energy_used_j": self.energy_used_j,
            "flight_time_s": self.flight_time_s,
            "nfz_violations": self.nfz_violations,
            "cells": [list(c) for c in self.cells],
        }


class ActionReplay:
    """A policy that flies a fixed list of actions, then lands: a mission read from a file."""

    def __init__(self, actions: list[int], name: str = "waypoint file"):
        self.actions = [int(a) for a in actions]
        self.name = name
        self._next = 0

    def reset(self, num_episodes: int, seed: int | None = None) -> None:
        self._next = 0

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        n = np.shape(obs["coverage"])[0]
        action = self.actions[self._next] if self._next < len(self.actions) else LAND
        self._next += 1
        return np.full(n, action, dtype=np.int64)


def fly_episode(
    policy: Any, grid_map: GridMap, config: PhysicsConfig, *, budget: int, start: Cell,
    seed: int = 0, any_map: bool = False,
) -> FlownRoute:  # fmt: skip
    """Fly one episode of ``policy`` on ``grid_map`` in MuJoCo from ``start`` with ``budget``
    units; a policy that says it does not fit the map is refused unless ``any_map``."""
    check_fits(policy, grid_map, any_map)
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=grid_map, config=config).unwrapped
    last: dict[str, np.ndarray] = {}

    def keep(action, obs, reward, info) -> None:
        last["coverage"] = np.asarray(obs["coverage"], dtype=bool)

    try:
        record = run_episode(
            env, policy, seed=seed, options={"start": tuple(start), "budget": int(budget)},
            on_step=keep,
        )  # fmt: skip
    finally:
        env.close()
    info = record.info
    width = grid_map.shape[1]
    cells = [divmod(int(c), width) for c in record.cells]
    route = [cells[0]] + [c for prev, c in zip(cells, cells[1:], strict=False) if c != prev]
    coverage = last.get("coverage", np.zeros(grid_map.shape, dtype=bool))
    return FlownRoute(
        policy=policy_name(policy) if not isinstance(policy, ActionReplay) else policy.name,
        start=(int(start[0]), int(start[1])),
        budget=int(budget),
        cells=[(int(r), int(c)) for r, c in route],
        actions=list(record.actions),
        landed=bool(info["landed"]),
        crash_reason=info.get("crash_reason"),
        coverage_ratio=float(info["coverage_ratio"]),
        seen=coverage & grid_map.target,
        energy_used_j=float(info.get("energy_used_j", 0.0)),
        flight_time_s=float(info.get("flight_time_s", 0.0)),
        nfz_violations=int(info.get("nfz_violations", 0)),
    )


def actions_between(cells: list[Cell]) -> list[int]:
    """The moves that fly through ``cells`` (each a neighbour of the one before, or the same
    cell), then the landing; ValueError naming the first pair that is not."""
    out = []
    for k, (here, there) in enumerate(zip(cells, cells[1:], strict=False), start=1):
        step = (there[0] - here[0], there[1] - here[1])
        if step == (0, 0):
            continue
        moves = [a for a in range(LAND) if tuple(MOVES[a]) == step]
        if not moves:
            raise ValueError(
                f"waypoint {k} (cell {there}) is not a neighbour of waypoint {k - 1} "
                f"(cell {here}): a mission moves one cell at a time"
            )
        out.append(moves[0])
    return out + [LAND]
