"""The grid's wind option, calibrated by flying: what each kind of action costs, per wind speed.

:mod:`cpp_mujoco.grid.wind` makes a grid move's cost depend on its direction relative to a
per-episode wind. Its numbers come from here: the action sequence of
:func:`~cpp_mujoco.physics.action_energy.flown_sequence` (out and back along each axis, a hover,
a landing) flown in MuJoCo at each speed, from each compass direction, over several gust
histories. Per speed, the four directions are pooled (a symmetric airframe: the steady rows are
identical, tested), giving the mean and standard deviation of each kind in budget units, the
lag-1 correlation of consecutive actions' standardized deviations (gusts last longer than one
action, so their costs are correlated) and the skewness of the moves' standardized deviations
(a move's energy is convex in the gust met, so its cost has a long right tail: ≈ 2.6 at 9 m/s,
where a log-normal of the same spread has ≈ 1). ``scripts/calibrate_grid_wind.py`` writes it.
"""

from __future__ import annotations

import hashlib
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from cpp_mujoco.physics.action_energy import KINDS, flown_sequence, weathers
from cpp_mujoco.physics.calibration import unit_energy
from cpp_mujoco.physics.config import PhysicsConfig

DIRECTIONS = (0.0, 90.0, 180.0, 270.0)
MOVE_KINDS = ("upwind", "downwind", "crosswind")


def _fly(args: tuple[PhysicsConfig, int]) -> list[tuple[str, float]]:
    config, seed = args
    return flown_sequence(config, seed)


def measure_wind_costs(
    base: PhysicsConfig | None = None,
    speeds: tuple[float, ...] = (0.0, 3.0, 6.0, 9.0, 12.0),
    turbulence: str = "moderate",
    repeats: int = 10,
    workers: int = 1,
) -> dict:
    """The table :class:`~cpp_mujoco.grid.wind.WindCosts` reads, with how it was made.

    ``turbulence`` applies above 0 m/s (calm air has none). Each speed × direction is flown
    ``repeats`` times with seeds 0, 1, …; ``workers`` processes share the flights.
    """
    base = base or PhysicsConfig()
    unit = unit_energy(base)
    jobs = [
        (config.wind_speed, (config, seed))
        for config in weathers(base, speeds, DIRECTIONS, turbulence)
        for seed in range(repeats)
    ]
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            flown = list(pool.map(_fly, [job for _, job in jobs]))
    else:
        flown = [_fly(job) for _, job in jobs]
    rows = []
    for speed in speeds:
        sequences = [seq for (s, _), seq in zip(jobs, flown, strict=True) if s == speed]
        rows.append(_pool(speed, sequences, unit))
    return {
        "unit_energy_j": unit,
        "turbulence": turbulence,
        "repeats": repeats,
        "directions": list(DIRECTIONS),
        "kinds": list(KINDS),
        "physics_digest": hashlib.sha256(repr(base).encode()).hexdigest()[:12],
        "speeds": rows,
    }


def _pool(speed: float, sequences: list[list[tuple[str, float]]], unit: float) -> dict:
    """Mean, std (units) per kind over the sequences, the lag-1 correlation of the
    standardized deviations of consecutive actions within a sequence, and the skewness of the
    moves' standardized deviations (what the grid's gust model reproduces)."""
    by_kind: dict[str, list[float]] = {k: [] for k in KINDS}
    for seq in sequences:
        for kind, joules in seq:
            by_kind[kind].append(joules / unit)
    if speed == 0.0:  # calm air has no heading to face: a move is a move
        for kind in ("upwind", "downwind"):
            by_kind[kind] = by_kind["crosswind"]
    mean = {k: float(np.mean(v)) for k, v in by_kind.items()}
    std = {k: float(np.std(v)) for k, v in by_kind.items()}
    pairs, moves = [], []
    for seq in sequences:
        # a spread below 0.1 % of the mean is numerical noise (calm air), not gusts
        z = [(j / unit - mean[k]) / std[k] if std[k] > 1e-3 * mean[k] else 0.0 for k, j in seq]
        pairs += list(zip(z[:-1], z[1:], strict=True))
        moves += [v for v, (k, _) in zip(z, seq, strict=True) if k in MOVE_KINDS]
    a = np.array(pairs)
    corr = float(np.corrcoef(a[:, 0], a[:, 1])[0, 1]) if a.std(axis=0).min() > 0 else 0.0
    m = np.array(moves)
    skew = float(np.mean((m - m.mean()) ** 3) / m.std() ** 3) if m.std() > 0 else 0.0
    return {
        "wind_speed": speed,
        "mean": mean,
        "std": std,
        "lag1_correlation": corr,
        "skewness": skew,
        "samples": {k: len(v) for k, v in by_kind.items()},
    }
