"""Dryden turbulence at low altitude (MIL-F-8785C "Atmospheric disturbances", MIL-HDBK-1797),
exactly discretised at the control rate.

The standard gives, below 1000 ft (h in ft, W20 = mean wind at 20 ft):
σ_w = 0.1·W20, σ_u = σ_v = σ_w / (0.177 + 0.000823·h)^0.4, L_w = h,
L_u = L_v = h / (0.177 + 0.000823·h)^1.2, and the Dryden correlations over the distance ξ = V·τ
the air moves past the vehicle (Taylor's frozen turbulence): u (along the mean wind)
R_u = σ_u²·exp(−ξ/L_u); v (across) and w (vertical) R = σ²·(1 − ξ/2L)·exp(−ξ/L). Their forming
filters are first order for u and (1 + √3·T·s)/(1 + T·s)² for v and w, T = L/V. Intensities:
W20 = 15 / 30 / 45 kt for light / moderate / severe (MIL-F-8785C; as in MathWorks' Dryden
Wind Turbulence Model blocks, which implement the same standard).

Discretisation (why exact): each filter is written in coordinates whose stationary covariance is
the identity, stepped with its exact transition matrix Φ = exp(A·dt) and a Gaussian kick of
covariance I − Φ·Φᵀ. The sampled sequence then has the continuous model's variance and
correlation at every lag, for any dt, and stays stationary while V (so T) changes per tick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

FOOT = 0.3048  # m
KNOT = 1852.0 / 3600.0  # m/s
W20_KNOTS = {"light": 15.0, "moderate": 30.0, "severe": 45.0}  # MIL-F-8785C low altitude
LEVELS = ("none", *W20_KNOTS)
MIN_ALTITUDE_FT = 10.0  # the low-altitude model is given for 10 ft <= h < 1000 ft
MAX_ALTITUDE_FT = 1000.0
# m/s: the airspeed in T = L/V never drops below this. Taylor's hypothesis needs air moving past
# the vehicle; at hover it would freeze the gust (T → ∞), while real turbulence also evolves in
# time. 1 m/s bounds the time scales at the standard's lengths: L_u/1 m/s ≈ 43 s, L_w ≈ 6 s at 6 m.
MIN_AIRSPEED = 1.0


def check_level(level: object, altitude_m: float) -> None:
    """``ValueError`` naming the option unless ``level`` is a known intensity usable at
    ``altitude_m`` (the low-altitude model ends at 1000 ft)."""
    if not isinstance(level, str) or level not in LEVELS:
        raise ValueError(f"turbulence must be one of {', '.join(map(repr, LEVELS))}, got {level!r}")
    if level != "none" and altitude_m / FOOT >= MAX_ALTITUDE_FT:
        raise ValueError(
            f"turbulence={level!r}: the low-altitude Dryden model holds below 1000 ft "
            f"({MAX_ALTITUDE_FT * FOOT:g} m), altitude is {altitude_m:g} m"
        )


@dataclass(frozen=True)
class DrydenParams:
    """Intensities (m/s) and scale lengths (m) of the three gust components."""

    sigma_u: float
    sigma_v: float
    sigma_w: float
    length_u: float
    length_v: float
    length_w: float

    @classmethod
    def low_altitude(cls, level: str, altitude_m: float) -> DrydenParams:
        """MIL-F-8785C low-altitude values for ``level`` at ``altitude_m`` (clamped to ≥ 10 ft)."""
        check_level(level, altitude_m)
        if level == "none":
            raise ValueError("turbulence='none' has no Dryden parameters")
        h = max(altitude_m / FOOT, MIN_ALTITUDE_FT)
        base = 0.177 + 0.000823 * h
        sigma_w = 0.1 * W20_KNOTS[level] * KNOT
        sigma_uv = sigma_w / base**0.4
        length_uv = h / base**1.2 * FOOT
        return cls(sigma_uv, sigma_uv, sigma_w, length_uv, length_uv, h * FOOT)

    def sigma(self, axis: str) -> float:
        return getattr(self, f"sigma_{axis}")

    def length(self, axis: str) -> float:
        return getattr(self, f"length_{axis}")


def correlation(axis: str, xi, length: float):
    """The Dryden normalised autocorrelation at separation ``xi`` (m): exp for ``"u"``, the
    transverse form (1 − ξ/2L)·exp(−ξ/L) for ``"v"`` and ``"w"``."""
    x = np.asarray(xi, dtype=float) / length
    return np.exp(-x) if axis == "u" else (1.0 - 0.5 * x) * np.exp(-x)


def _tail3(x: float) -> float:
    """1 − e^(−x)·(1 + x + x²/2), without the cancellation for small x (≈ x³/6)."""
    if x >= 0.5:
        return 1.0 - math.exp(-x) * (1.0 + x + 0.5 * x * x)
    s = 1.0 + x / 15.0  # Σ_{k≥3} x^k/k!: the terms beyond x^15 are < 1e-16 of the sum
    for k in range(14, 3, -1):
        s = 1.0 + x / k * s
    return math.exp(-x) * x * x * x / 6.0 * s


def first_order(r: float) -> tuple[float, float]:
    """(decay, kick) of a unit-variance first-order process over r = dt/T."""
    return math.exp(-r), math.sqrt(-math.expm1(-2.0 * r))


def second_order(r: float) -> tuple[float, ...]:
    """Exact step of the critically damped pair (unit, uncorrelated stationary states) over
    r = dt/T: Φ = e^(−r)·[[1+r, r], [−r, 1−r]] and the Cholesky factor of I − Φ·Φᵀ."""
    e = math.exp(-r)
    x = 2.0 * r
    q11 = _tail3(x)
    q12 = 0.5 * x * x * e * e
    q22 = 1.0 - e * e * (1.0 - x + 0.5 * x * x)
    l11 = math.sqrt(q11)
    l21 = q12 / l11
    l22 = math.sqrt(max(q22 - l21 * l21, 0.0))
    return e * (1.0 + r), e * r, -e * r, e * (1.0 - r), l11, l21, l22


class DrydenTurbulence:
    """The three forming filters' exact coefficients at the control rate ``dt``, for the air
    moving past at a given airspeed (the filters run in the tick's kernel,
    :func:`~cpp_mujoco.physics.tick_kernels.dryden_step`).

    The airspeed in the time scales is rounded to a geometric grid of ``airspeed_step``
    (relative, default 0.5 %: T = L/V off by at most 0.25 %) so that each tick looks its
    coefficients up (:class:`~cpp_mujoco.physics.air.wind.Wind` tables them) instead of
    recomputing them (≈ 10 µs) as the UAV's airspeed changes. The rounding keeps every axis
    exactly stationary with its σ: only its time scale is rounded.
    """

    def __init__(
        self, params: DrydenParams, dt: float, min_airspeed: float = MIN_AIRSPEED,
        airspeed_step: float = 0.005,
    ):  # fmt: skip
        if not airspeed_step > 0:
            raise ValueError("the turbulence tables its coefficients: airspeed_step must be > 0")
        self.params, self.dt, self.min_airspeed = params, dt, min_airspeed
        p = params
        self.gain = (p.sigma_u, 0.5 * p.sigma_v, 0.5 * p.sigma_w)
        self.per_log = 1.0 / math.log1p(airspeed_step)

    def effective_airspeed(self, airspeed: float) -> float:
        """The V (m/s) the time scales use for ``airspeed``: at least ``min_airspeed``, rounded
        to the grid."""
        airspeed = max(airspeed, self.min_airspeed)
        return math.exp(round(math.log(airspeed) * self.per_log) / self.per_log)

    def coefficients(self, airspeed: float) -> tuple:
        """The 16 coefficients of one tick at ``airspeed`` (m/s, used as given): u's (decay,
        kick), then v's and w's :func:`second_order`."""
        p, dt = self.params, self.dt
        return (
            *first_order(dt * airspeed / p.length_u),
            *second_order(dt * airspeed / p.length_v),
            *second_order(dt * airspeed / p.length_w),
        )

    def sequence(self, airspeed: float, ticks: int, rng: np.random.Generator) -> np.ndarray:
        """``ticks`` consecutive gusts (u, v, w in m/s, (ticks, 3)) at a fixed airspeed, the
        filters started from their stationary distribution: the flight's own kernel, fed the
        normals in the order a drone's wind takes them (blocks of 1000 popped from the end)."""
        from cpp_mujoco.physics.tick_kernels import dryden_step  # heavy: numba, off physics.config

        need = 5 + 5 * ticks
        blocks = [rng.standard_normal(1000)[::-1] for _ in range(-(-need // 1000))]
        taken = np.concatenate(blocks)[:need]
        state, noise = taken[:5].copy(), taken[5:][::-1].copy()
        coefficients = np.array(self.coefficients(self.effective_airspeed(airspeed)))
        out = [dryden_step(coefficients, state, noise, noise.size - 5 * k) for k in range(ticks)]
        return np.array(out) * np.array(self.gain)


def measure(gusts: np.ndarray, dt: float, airspeed: float, params: DrydenParams) -> dict:
    """Per axis: the sample std, the autocorrelation at lag L/V and the scale length L fitted to
    the sample autocorrelation over lags up to 2L/V (least squares on the Dryden shape)."""
    out = {}
    for i, axis in enumerate("uvw"):
        x = gusts[:, i] - gusts[:, i].mean()
        length = params.length(axis)
        lags = int(round(2.0 * length / (airspeed * dt)))
        n = len(x)
        spectrum = np.fft.rfft(x, 2 * n)
        acov = np.fft.irfft(spectrum * spectrum.conj())[: lags + 1] / np.arange(n, n - lags - 1, -1)
        rho = acov / acov[0]
        xi = np.arange(lags + 1) * airspeed * dt
        at_l = float(np.interp(length, xi, rho))
        grid = length * np.linspace(0.5, 2.0, 301)
        errors = [float(np.sum((rho - correlation(axis, xi, g)) ** 2)) for g in grid]
        out[axis] = {
            "std": float(np.sqrt(acov[0])),
            "sigma": params.sigma(axis),
            "rho_at_L": at_l,
            "rho_at_L_model": float(correlation(axis, length, length)),
            "length_fit": float(grid[int(np.argmin(errors))]),
            "length": length,
        }
    return out


def statistics_table(
    airspeed: float = 10.0, ticks: int = 2_000_000, dt: float = 0.02, altitude_m: float = 6.0
) -> str:
    """Markdown table: generated vs model statistics for each level, each from its own seed
    (``python -m cpp_mujoco.physics.air.turbulence``; docs/turbulence.md)."""
    rows = ["| level | axis | σ model | σ measured | ρ(L/V) model | ρ(L/V) measured | "
            "L model | L fitted |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for seed, level in enumerate(W20_KNOTS):
        params = DrydenParams.low_altitude(level, altitude_m)
        turbulence = DrydenTurbulence(params, dt)
        speed = turbulence.effective_airspeed(airspeed)
        gusts = turbulence.sequence(speed, ticks, np.random.default_rng(seed))
        stats = measure(gusts, dt, speed, params)
        for axis, s in stats.items():
            rows.append(
                f"| {level} | {axis} | {s['sigma']:.3f} | {s['std']:.3f} | "
                f"{s['rho_at_L_model']:.3f} | {s['rho_at_L']:.3f} | {s['length']:.1f} | "
                f"{s['length_fit']:.1f} |"
            )
    return "\n".join(rows)


if __name__ == "__main__":
    print(statistics_table())
