"""How well the grid's gust costs match MuJoCo's: the tail of the cost of a way home.

    python scripts/gust_tail.py [--speed 9] [--flights 40] [--rounds 6] [--workers 2] [--out DIR]

Flies long random out-and-back move sequences in MuJoCo (moderate turbulence, the wind from each
of N/E/S/W, ``--flights`` gust histories per direction, ``--rounds`` × 8 moves each), then draws
the grid wind option's costs for the very same kind sequences, and compares the excess over the
mean cost of k consecutive moves (k = 1, 2, 4, 8, 12; what a way home of k moves costs more than
planned): standard deviation, 99th and 99.9th percentile, and the lag-1 correlation. A
log-normal AR(1) factor with the same mean, spread and correlation (the grid's earlier model) is
drawn beside it. Writes DIR/gust_tail.json (every number, with the weather and the table it used)
and DIR/gust_tail.png (exceedance of the 4-move excess).
"""

from __future__ import annotations

import argparse
import json
import math
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from cpp_mujoco.grid.wind import (
    KIND_INDEX,
    action_costs,
    episode_costs,
    next_gust,
    wind_costs,
)
from cpp_mujoco.physics.action import HOVER, MOVE
from cpp_mujoco.physics.action_energy import _HEADINGS, _OPEN, _kind
from cpp_mujoco.physics.calibration import unit_energy
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.flight import Flight
from cpp_mujoco.util.io import atomic_path, atomic_write_text

SUMS = (1, 2, 4, 8, 12)


def fly(job: tuple[float, float, int, int]) -> list[tuple[int, float]]:
    """One flight: ``rounds`` × the four headings in a random order, out of the middle cell and
    back; [(kind index, joules), …]."""
    speed, direction, seed, rounds = job
    config = replace(
        PhysicsConfig(), wind_speed=speed, wind_direction=direction, turbulence="moderate"
    )
    flight = Flight.alone(_OPEN, config)
    width, middle = _OPEN.shape[1], 2 * _OPEN.shape[1] + 2
    flight.reset(0, 2, 2, math.inf, np.random.default_rng(seed))
    flight.fly_one(HOVER, middle)  # settle
    order = np.random.default_rng(10_000 + seed)
    sequence = []
    for _ in range(rounds):
        for heading in order.permutation(list(_HEADINGS)):
            row, col = _HEADINGS[heading]
            out, back = flight.fly_one(MOVE, row * width + col), flight.fly_one(MOVE, middle)
            for h, result in ((heading, out), ((heading + 180.0) % 360.0, back)):
                if result.failure is not None:
                    raise RuntimeError(f"flight {job} failed: {result.failure}")
                sequence.append((KIND_INDEX[_kind(h, direction)], result.energy))
    return sequence


def grid_costs(kinds: np.ndarray, speed: float, repeats: int, model: str) -> np.ndarray:
    """Costs the grid draws for the kind sequences ``kinds`` (n, T), ``repeats`` gust streams
    each: ``model`` "grid" (the option's) or "lognormal" (same mean, spread and correlation)."""
    table = wind_costs()
    kinds = np.tile(kinds, (repeats, 1))
    n, steps = kinds.shape
    mean, std, b, rho = episode_costs(np.full(n, speed), table)
    keys = np.arange(n, dtype=np.int64) * 7919 + 1
    if model == "lognormal":
        _, _, rho = table.at(np.full(n, speed))
        b = None
    gust, out = np.zeros(n), np.empty((n, steps))
    for t in range(steps):
        gust = next_gust(gust, keys, np.full(n, t), rho)
        if b is None:
            rows = np.arange(n)
            m, s = mean[rows, kinds[:, t]], std[rows, kinds[:, t]]
            sigma = np.sqrt(np.log1p((s / m) ** 2))
            out[:, t] = m * np.exp(sigma * gust - 0.5 * sigma**2)
        else:
            out[:, t] = action_costs(kinds[:, t], mean, std, b, gust, True)
    return out


def tail(excess: np.ndarray) -> dict:
    """Per k: std, 99th and 99.9th percentile of the summed excess of k consecutive moves."""
    rows = {}
    for k in SUMS:
        sums = np.lib.stride_tricks.sliding_window_view(excess, k, axis=1).sum(-1).ravel()
        rows[str(k)] = {
            "std": float(sums.std()),
            "p99": float(np.percentile(sums, 99)),
            "p99_9": float(np.percentile(sums, 99.9)),
        }
    z = excess - excess.mean()
    rows["lag1_correlation"] = float(np.mean(z[:, :-1] * z[:, 1:]) / z.var())
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=float, default=9.0)
    parser.add_argument("--flights", type=int, default=40, help="gust histories per direction")
    parser.add_argument("--rounds", type=int, default=6, help="8 moves per round")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("out/gust_tail"))
    args = parser.parse_args()
    if not 0 < args.speed <= wind_costs().speeds[-1] or args.flights < 1 or args.rounds < 1:
        parser.error("need 0 < --speed <= 12 m/s (the calibrated range), --flights, --rounds >= 1")
    jobs = [(args.speed, d, s, args.rounds) for d in (0.0, 90.0, 180.0, 270.0)
            for s in range(args.flights)]  # fmt: skip
    with ProcessPoolExecutor(args.workers) as pool:
        flown = list(pool.map(fly, jobs))
    unit = unit_energy(PhysicsConfig())
    kinds = np.array([[k for k, _ in seq] for seq in flown])
    cost = {"mujoco": np.array([[j / unit for _, j in seq] for seq in flown])}
    cost["grid"] = grid_costs(kinds, args.speed, 20, "grid")
    cost["lognormal"] = grid_costs(kinds, args.speed, 20, "lognormal")
    mean = wind_costs().at(np.array([args.speed]))[0][0]
    excess = {name: c - mean[np.tile(kinds, (len(c) // len(kinds), 1))] for name, c in cost.items()}
    result = {
        "command": f"python scripts/gust_tail.py --speed {args.speed:g} --flights {args.flights} "
        f"--rounds {args.rounds}",
        "conditions": {"wind_speed": args.speed, "directions": "each of N/E/S/W",
                       "turbulence": "moderate", "flights": len(flown),
                       "moves_per_flight": int(kinds.shape[1]),
                       "table": wind_costs().source.get("command"),
                       "physics_digest": wind_costs().source.get("physics_digest")},
        "excess_over_mean_cost_units": {name: tail(e) for name, e in excess.items()},
    }  # fmt: skip
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out / "gust_tail.json", json.dumps(result, indent=1) + "\n")
    print(f"excess over the mean cost of k moves, {args.speed:g} m/s moderate, units")
    print("| k | MuJoCo std / p99 / p99.9 | grid model | log-normal AR(1) |\n|---|---|---|---|")
    rows = result["excess_over_mean_cost_units"]
    for k in map(str, SUMS):
        cells = [f"{r[k]['std']:.2f} / {r[k]['p99']:.2f} / {r[k]['p99_9']:.2f}" for r in
                 (rows["mujoco"], rows["grid"], rows["lognormal"])]  # fmt: skip
        print(f"| {k} | " + " | ".join(cells) + " |")
    print(
        "lag-1 correlation: "
        + ", ".join(f"{n} {r['lag1_correlation']:.2f}" for n, r in rows.items())
    )
    fig = Figure(figsize=(6, 4), layout="constrained")
    ax = fig.add_subplot()
    for name, e in excess.items():
        sums = np.sort(np.lib.stride_tricks.sliding_window_view(e, 4, axis=1).sum(-1).ravel())
        ax.semilogy(sums, 1.0 - np.arange(sums.size) / sums.size, label=name)
    ax.set(xlabel="excess cost of 4 consecutive moves over their mean (units)",
           ylabel="P(excess ≥ x)", ylim=(1e-4, 1),
           title=f"gust cost tail, {args.speed:g} m/s moderate, wind from N/E/S/W")  # fmt: skip
    ax.legend()
    with atomic_path(args.out / "gust_tail.png") as tmp:
        fig.savefig(tmp, dpi=120)
    print(f"wrote {args.out}/gust_tail.json and gust_tail.png")


if __name__ == "__main__":
    main()
