"""The protocol flown in wind from the four compass directions, and the rated wind.

Why the budgets are dealt out: a wind from the north and one from the east are different
missions (upwind legs, the way home), so a sweep must fly all four; flying the whole protocol
four times quadruples the cost. Dealing the protocol's budgets round-robin to the directions
(north gets 25, 29, …; east 26, 30, …) flies every landing cell × budget exactly once, each
direction over the whole budget range, and :func:`concatenate` joins the four runs into one
result whose conditions say which episodes flew in which wind.
"""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import nullcontext
from typing import Any

import numpy as np

from cpp_mujoco.maps import GridMap
from cpp_mujoco.protocol.evaluate import (
    EvaluationResult,
    evaluate,
    protocol_budgets,
    split_conditions,
)
from cpp_mujoco.protocol.ray_engine import ray_runtime

# The wind up to which the flight keeps out of no-fly airspace (``nfz_violations == 0`` over the
# protocol on the bundled maps, every bundled policy; measured by ``scripts/rated_wind.py``):
# a 9 m/s steady wind (Beaufort 5, "fresh breeze") with MIL-F-8785C moderate turbulence.
RATED_WIND: dict[str, Any] = {"wind_speed": 9.0, "turbulence": "moderate"}
COMPASS = (0.0, 90.0, 180.0, 270.0)  # where the wind blows from: north, east, south, west
COMPASS_NAMES = {0.0: "N", 90.0: "E", 180.0: "S", 270.0: "W"}


def concatenate(results: Sequence[EvaluationResult], *, repeated: bool = False) -> EvaluationResult:
    """One result from runs of one policy on one map and backend over disjoint episodes
    (``repeated``: the parts may fly the same episodes, each part under its own conditions —
    the same protocol from each wind direction).

    ``conditions``: what the parts share, ``episodes`` in all, and ``parts`` — each part's own
    conditions (its wind direction, its budgets), in order.
    """
    if not results:
        raise ValueError("nothing to concatenate")
    first = results[0]
    for other in results[1:]:
        same = (other.grid_map.digest, other.policy_name, other.backend)
        if same != (first.grid_map.digest, first.policy_name, first.backend):
            raise ValueError(
                f"cannot join results of {other.map_name}/{other.policy_name}/{other.backend} "
                f"and {first.map_name}/{first.policy_name}/{first.backend}"
            )
    episodes = [(tuple(s), int(b)) for r in results for s, b in zip(r.starts, r.budgets)]  # noqa: B905
    if not repeated and len(set(episodes)) != len(episodes):
        raise ValueError("the parts share episodes (a start and budget flown twice)")
    length = max(r.trajectories.shape[1] for r in results)
    trajectories = np.full((len(episodes), length), -1, dtype=np.int64)
    row = 0
    for r in results:
        trajectories[row : row + len(r.budgets), : r.trajectories.shape[1]] = r.trajectories
        row += len(r.budgets)
    shared, own = split_conditions([r.conditions for r in results])
    if repeated and len({repr(c) for c in own}) != len(own):
        raise ValueError("repeated episodes need each part's own conditions (e.g. its wind)")
    keys = set(first.physics)
    if any(set(r.physics) != keys for r in results):
        raise ValueError("the parts carry different physical figures")

    def joined(name: str) -> np.ndarray:
        return np.concatenate([getattr(r, name) for r in results])

    return EvaluationResult(
        grid_map=first.grid_map,
        policy_name=first.policy_name,
        backend=first.backend,
        starts=joined("starts"),
        budgets=joined("budgets"),
        landed=joined("landed"),
        coverage=joined("coverage"),
        steps=joined("steps"),
        returns=joined("returns"),
        trajectories=trajectories,
        upper_bound={k: v for r in results for k, v in r.upper_bound.items()},
        physics={k: np.concatenate([r.physics[k] for r in results]) for k in first.physics},
        conditions={
            **shared,
            "episodes": len(episodes),
            "parts": own,
            **({"directions": "each"} if repeated else {}),
        },  # fmt: skip
    )


def evaluate_in_winds(
    policy,
    grid_map: GridMap,
    wind_speed: float,
    *,
    turbulence: str = "none",
    budgets: Sequence[int] | None = None,
    policy_name: str | None = None,
    workers: int | None = None,
    progress: bool = False,
    env_kwargs: dict | None = None,
    engine: str = "local",
    ray_address: str | None = None,
    each_direction: bool = False,
) -> EvaluationResult:
    """The protocol (``budgets``, default all) in MuJoCo with a ``wind_speed`` wind from the
    four compass directions, the budgets dealt round-robin to them (see the module docstring);
    ``each_direction``: every episode from every direction instead (4× the episodes; the
    result's conditions say ``directions: each``).
    In calm air (speed 0) the direction means nothing: one run. ``engine``, ``ray_address``:
    as :func:`~cpp_mujoco.protocol.evaluate.evaluate`; Ray is started (or connected) once for the
    four."""
    budgets = sorted(budgets if budgets is not None else protocol_budgets())
    weather = {**(env_kwargs or {}), "wind_speed": wind_speed, "turbulence": turbulence}
    directions = COMPASS if wind_speed > 0 else (0.0,)
    runtime = nullcontext()
    if engine == "ray":
        runtime = ray_runtime(ray_address, workers)
    with runtime:
        parts = [
            evaluate(
                policy,
                grid_map,
                backend="mujoco",
                budgets=budgets if each_direction else budgets[k :: len(directions)],
                policy_name=policy_name,
                workers=workers,
                progress=progress,
                env_kwargs={**weather, "wind_direction": direction},
                engine=engine,
                ray_address=ray_address,
            )  # fmt: skip
            for k, direction in enumerate(directions)
            if each_direction or budgets[k :: len(directions)]
        ]
    return concatenate(parts, repeated=each_direction and len(parts) > 1)
