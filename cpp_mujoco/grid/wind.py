"""The grid MDP's power-variation option: a per-episode wind that sets what each action costs.

The paper charges one budget unit per action. In physics an action's energy depends on its
heading relative to the wind and, in turbulence, on the gusts met on the way (measured per kind
in ``wind_costs.json``, flown in MuJoCo by ``scripts/calibrate_grid_wind.py``). With
``GridConfig(wind=GridWind())`` each episode draws a steady wind — calm with probability
``calm_fraction``, else a speed uniform over ``min_speed..max_speed`` — blowing from one of the
compass directions in ``directions``; then

* a move costs the calibrated mean for its kind (upwind, downwind or crosswind) at that speed
  (linear in speed between the flown speeds), a rejected action a hover's, a landing a landing's;
* with ``turbulence`` a gust term is added: the measured spread times z = a·g + b·(g² − 1), a
  linear plus a quadratic function of a standard normal gust state g that follows an AR(1)
  process over the episode's actions. Why this form: the Dryden gust velocity is Gaussian and a
  move's energy is convex in it (rotor power grows with airspeed), so gust costs have a long
  right tail — skewness ≈ 2.6 at 9 m/s, where a log-normal of the same spread has ≈ 1 and put
  the 99th percentile of a 4-move way home 1.1 units too low. b is solved from the measured
  skewness (6b − 4b³, a² = 1 − 2b²), g's correlation from the measured lag-1 correlation of the
  costs (a²ρ + 2b²ρ²); z has mean 0 and variance 1, so each kind keeps its mean and spread;
* the budget is a float; the observation shows it in whole units (floored, as the physics env
  does) and adds the wind's velocity (``wind``, east and north in m/s), as a flight controller's
  wind estimate would.

The random numbers of the gusts are a counter-based hash of a per-episode key and the action
index, so they are the same whichever batch an episode is stepped in, and need no generator.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

COSTS_FILE = Path(__file__).resolve().parent / "wind_costs.json"
COMPASS = ("N", "E", "S", "W")  # where the wind blows from; index = the action heading it faces
KIND_INDEX = {"upwind": 0, "downwind": 1, "crosswind": 2, "hover": 3, "land": 4}


@dataclass(frozen=True)
class GridWind:
    """Per-episode wind for the grid MDP (defaults: the range the wind sweep flies)."""

    min_speed: float = 0.0  # m/s, lower end of the uniform speed draw
    max_speed: float = 12.0  # m/s, upper end (the calibration flies up to 12 m/s)
    calm_fraction: float = 0.2  # share of episodes in calm air (exactly 0 m/s)
    directions: tuple[str, ...] = COMPASS  # compass directions the wind may blow from
    turbulence: bool = True  # draw gust costs (moderate turbulence); False: the means only
    # per-episode multiplier of the calibrated gust spread, uniform over this range: the
    # turbulence intensity of a day is uncertain (MIL-F-8785C gives σ only by probability of
    # exceedance), and one calibrated intensity taught the agents too thin a margin
    gust_scale: tuple[float, float] = (1.0, 1.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "directions", tuple(self.directions))
        object.__setattr__(self, "gust_scale", tuple(float(v) for v in self.gust_scale))
        lo, hi = self.gust_scale
        if not (np.isfinite([lo, hi]).all() and 0.0 < lo <= hi <= 4.0):
            raise ValueError(f"gust_scale must be (lo, hi) with 0 < lo <= hi <= 4, got {lo, hi}")
        speeds = (self.min_speed, self.max_speed, self.calm_fraction)
        if not all(np.isfinite(speeds)):
            raise ValueError(f"wind speeds and calm_fraction must be finite, got {speeds}")
        top = wind_costs().speeds[-1]
        if not 0.0 <= self.min_speed <= self.max_speed <= top:
            raise ValueError(
                f"need 0 <= min_speed <= max_speed <= {top:g} m/s (the calibrated range), "
                f"got {self.min_speed}..{self.max_speed}"
            )
        if not 0.0 <= self.calm_fraction <= 1.0:
            raise ValueError(f"calm_fraction must be in [0, 1], got {self.calm_fraction}")
        bad = [d for d in self.directions if d not in COMPASS]
        if not self.directions or bad:
            raise ValueError(f"directions must be some of {COMPASS}, got {self.directions!r}")

    def draw(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(speed m/s, direction it blows from in degrees clockwise from north, gust key) per
        row of uniforms ``u`` (k, 3) in [0, 1)."""
        u = np.asarray(u, dtype=np.float64).reshape(-1, 3)
        calm = u[:, 0] < self.calm_fraction
        rest = (u[:, 0] - self.calm_fraction) / max(1.0 - self.calm_fraction, 1e-12)
        speed = np.where(calm, 0.0, self.min_speed + rest * (self.max_speed - self.min_speed))
        allowed = np.array([COMPASS.index(d) for d in self.directions])
        direction = 90.0 * allowed[(u[:, 1] * allowed.size).astype(np.int64)]
        key = (u[:, 2] * 2.0**53).astype(np.int64)
        return speed, direction, key


@dataclass(frozen=True)
class WindCosts:
    """The calibrated table: per flown speed, mean and std (units) of each kind, and the lag-1
    correlation of consecutive actions' deviations."""

    speeds: np.ndarray  # (S,)
    mean: np.ndarray  # (S, 5) in KIND_INDEX order
    std: np.ndarray  # (S, 5)
    correlation: np.ndarray  # (S,) lag-1 correlation of consecutive actions' costs
    skewness: np.ndarray  # (S,) skewness of a move's standardized cost
    source: dict  # the file's provenance (unit energy, turbulence, command)

    def at(self, speed: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(mean (N,5), std (N,5), correlation (N,)) at each speed, linear between flown ones."""
        speed = np.asarray(speed, dtype=np.float64)
        mean = np.stack([np.interp(speed, self.speeds, self.mean[:, k]) for k in range(5)], -1)
        std = np.stack([np.interp(speed, self.speeds, self.std[:, k]) for k in range(5)], -1)
        return mean, std, np.interp(speed, self.speeds, self.correlation)

    def gust_shape(self, speed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(quadratic weight b (N,), gust-state correlation ρ_g (N,)) at each speed: solved at
        the flown speeds from their skewness and correlation, linear in between."""
        b, rho = gust_shape(self.skewness, self.correlation)
        speed = np.asarray(speed, dtype=np.float64)
        return np.interp(speed, self.speeds, b), np.interp(speed, self.speeds, rho)


@functools.cache
def wind_costs(path: str | Path = COSTS_FILE) -> WindCosts:
    """The table in ``path`` (default: the bundled calibration); ``ValueError`` if malformed."""
    try:
        data = json.loads(Path(path).read_text())
        rows = sorted(data["speeds"], key=lambda r: r["wind_speed"])
        kinds = list(KIND_INDEX)
        table = WindCosts(
            speeds=np.array([r["wind_speed"] for r in rows], dtype=np.float64),
            mean=np.array([[r["mean"][k] for k in kinds] for r in rows], dtype=np.float64),
            std=np.array([[r["std"][k] for k in kinds] for r in rows], dtype=np.float64),
            correlation=np.array([r["lag1_correlation"] for r in rows], dtype=np.float64),
            skewness=np.array([r["skewness"] for r in rows], dtype=np.float64),
            source={k: v for k, v in data.items() if k != "speeds"},
        )
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"wind cost table {path} is unreadable or malformed: {exc}") from None
    ok = (
        table.speeds.size >= 2
        and table.speeds[0] == 0.0
        and (np.diff(table.speeds) > 0).all()
        and np.isfinite(table.mean).all()
        and (table.mean > 0).all()
        and (table.std >= 0).all()
        and (np.abs(table.correlation) < 1).all()
        and np.isfinite(table.skewness).all()
    )
    if not ok:
        raise ValueError(f"wind cost table {path}: speeds must start at 0 and rise, costs be > 0")
    return table


def action_kind(actions: np.ndarray, rejected: np.ndarray, lands: np.ndarray, wind_from):
    """KIND_INDEX of each action: a landing, a hover (rejected), or a move whose heading
    (action 0..3 = N, E, S, W) faces the wind (within 45° of where it blows from: upwind), runs
    with it (downwind) or across it."""
    offset = (90.0 * np.asarray(actions) - np.asarray(wind_from)) % 360.0
    move = np.where((offset < 45) | (offset > 315), 0, np.where(np.abs(offset - 180) < 45, 1, 2))
    return np.where(lands, 4, np.where(rejected, 3, move))


def wind_velocity(speed: np.ndarray, wind_from: np.ndarray) -> np.ndarray:
    """(N, 2) east and north components (m/s) of the air's velocity for a wind blowing from
    ``wind_from`` degrees clockwise from north — the physics config's convention."""
    rad = np.radians(np.asarray(wind_from, dtype=np.float64))
    speed = np.asarray(speed, dtype=np.float64)
    velocity = np.stack([-speed * np.sin(rad), -speed * np.cos(rad)], axis=-1)
    return np.round(velocity, 6).astype(np.float32)  # sin(180°) is 1e-16, not 0


def _mix(x: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser (uint64 in, uint64 out; wraps around by design)."""
    x = x + np.uint64(0x9E3779B97F4A7C15)
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


def gust_uniform(key: np.ndarray) -> np.ndarray:
    """One uniform in [0, 1) per gust key, apart from the key's gust stream (the episode's
    turbulence intensity: no extra draw from the reset generator, so seeds keep their winds)."""
    with np.errstate(over="ignore"):
        a = _mix(np.asarray(key).astype(np.uint64) ^ np.uint64(0xD1B54A32D192ED03))
    return (a >> np.uint64(11)).astype(np.float64) / 2.0**53


def gust_normal(key: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Standard normal draws, one per (key, step): splitmix64 of the pair, then Box–Muller."""
    with np.errstate(over="ignore"):
        key, step = np.asarray(key).astype(np.uint64), np.asarray(step).astype(np.uint64)
        a = _mix(key ^ _mix(step))
        b = _mix(a)
    u1 = ((a >> np.uint64(11)).astype(np.float64) + 0.5) / 2.0**53  # (0, 1)
    u2 = (b >> np.uint64(11)).astype(np.float64) / 2.0**53
    return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)


MAX_QUADRATIC = 1.0 / np.sqrt(2.0)  # b at which z = (g² − 1)/√2: the largest skewness, 2√2
MIN_COST_SHARE = 0.05  # a gust never makes an action cost less than this share of its mean


def gust_shape(skewness, correlation) -> tuple[np.ndarray, np.ndarray]:
    """(b, ρ_g) of z = a·g + b·(g² − 1), a = √(1 − 2b²), g an AR(1) standard normal state:
    b gives z the skewness 6b − 4b³ (clipped to 0..2√2), ρ_g gives consecutive z the
    correlation a²ρ_g + 2b²ρ_g²."""
    skew = np.clip(np.asarray(skewness, dtype=np.float64), 0.0, 2.0 * np.sqrt(2.0))
    grid = np.linspace(0.0, MAX_QUADRATIC, 2001)  # 6b − 4b³ rises monotonically on it
    b = np.interp(skew, 6.0 * grid - 4.0 * grid**3, grid)
    a2, r1 = 1.0 - 2.0 * b**2, np.clip(np.asarray(correlation, dtype=np.float64), 0.0, 0.99)
    c2 = 2.0 * b**2
    with np.errstate(invalid="ignore", divide="ignore"):
        quad = (-a2 + np.sqrt(a2**2 + 4.0 * c2 * r1)) / (2.0 * c2)
    rho = np.where(c2 > 1e-12, quad, r1 / np.maximum(a2, 1e-12))
    return b, np.clip(rho, 0.0, 0.99)


def episode_costs(speed: np.ndarray, table: WindCosts) -> tuple[np.ndarray, ...]:
    """Per episode, from its wind speed: mean (N, 5) and spread (N, 5) of each kind, the gust
    term's quadratic weight b (N,) and the gust state's correlation ρ_g (N,) — looked up once
    per episode."""
    mean, std, _ = table.at(speed)
    b, rho = table.gust_shape(speed)
    return mean, std, b, rho


def action_costs(kind, mean, std, b, gust, turbulence: bool) -> np.ndarray:
    """Cost (units) of each env's action of ``kind``: its episode's mean for that kind, plus
    with turbulence the spread times z = a·g + b·(g² − 1) of the gust state g."""
    rows = np.arange(np.size(kind))
    m = mean[rows, kind]
    if not turbulence:
        return m
    z = np.sqrt(1.0 - 2.0 * b**2) * gust + b * (gust**2 - 1.0)
    return np.maximum(m + std[rows, kind] * z, MIN_COST_SHARE * m)


def next_gust(gust, key, step, rho) -> np.ndarray:
    """The AR(1) gust state after one more action: ρ·g + √(1−ρ²)·ε (ε for the first action)."""
    eps = gust_normal(key, step)
    return np.where(step == 0, eps, rho * gust + np.sqrt(1.0 - rho**2) * eps)


class EpisodeWinds:
    """The wind of N episodes held in arrays: what :class:`~cpp_mujoco.grid.mdp.GridMDP` keeps
    per environment for the wind option (and, for the observation, the physics env's wind)."""

    STATE = ("wind_speed", "wind_from", "gust_key", "gust", "actions_taken")  # saved arrays

    def __init__(self, num_envs: int, wind: GridWind | None):
        n = num_envs
        self.option = wind
        self.table = wind_costs() if wind is not None else None
        self.wind_speed = np.zeros(n)  # m/s
        self.wind_from = np.zeros(n)  # deg clockwise from north
        self.vector = np.zeros((n, 2), dtype=np.float32)  # east, north m/s: what is observed
        self.gust_key = np.zeros(n, dtype=np.int64)  # < 2**53, names the episode's gust stream
        self.gust = np.zeros(n)  # AR(1) state g, standard normal
        self.actions_taken = np.zeros(n, dtype=np.int64)
        # looked up from the speed once per episode: mean and spread per kind, gust shape
        self.mean, self.std = np.ones((n, 5)), np.zeros((n, 5))
        self.quadratic, self.rho = np.zeros(n), np.zeros(n)

    def draw(self, idx, u: np.ndarray) -> None:
        """New episodes' winds from uniforms ``u`` (k, 3) (:meth:`GridWind.draw`)."""
        speed, wind_from, key = self.option.draw(u)
        self.gust_key[idx] = key  # first: the episode's gust intensity derives from it
        self.set(idx, speed, wind_from)

    def set(self, idx, speed, wind_from) -> None:
        """The steady wind of envs ``idx``; the gust stream starts again."""
        self.wind_speed[idx] = speed
        self.wind_from[idx] = wind_from
        self.vector[idx] = wind_velocity(speed, wind_from)
        self.gust[idx] = 0.0
        self.actions_taken[idx] = 0
        self._lookup()

    def _lookup(self) -> None:
        if self.table is not None:
            self.mean, self.std, self.quadratic, self.rho = episode_costs(
                self.wind_speed, self.table
            )
            lo, hi = self.option.gust_scale  # each episode's turbulence intensity
            self.std = self.std * (lo + (hi - lo) * gust_uniform(self.gust_key))[:, None]

    def costs(self, actions, rejected, lands, active) -> np.ndarray:
        """Each active env's action cost in its episode's wind; the gust streams of active envs
        advance by one action."""
        gust = next_gust(self.gust, self.gust_key, self.actions_taken, self.rho)
        self.gust = np.where(active, gust, self.gust)
        self.actions_taken += active
        kind = action_kind(actions, rejected, lands, self.wind_from)
        cost = action_costs(
            kind, self.mean, self.std, self.quadratic, self.gust, self.option.turbulence
        )
        return np.where(active, cost, 0.0)

    def loaded(self) -> None:
        """Recompute what derives from the saved arrays after they were set."""
        self.vector = wind_velocity(self.wind_speed, self.wind_from)
        self._lookup()
