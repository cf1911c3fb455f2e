"""Dryden turbulence (MIL-F-8785C low altitude): parameters, exact discretisation, generated
statistics vs the model, seeding, validation, and its way into the flight and the protocol."""

import math

import gymnasium as gym
import numpy as np
import pytest
from scipy.linalg import expm
from scipy.special import gammainc

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.air import turbulence as tb
from cpp_mujoco.physics.air.turbulence import DrydenParams, DrydenTurbulence, correlation, measure
from cpp_mujoco.physics.air.wind import Wind
from cpp_mujoco.physics.calibration import calibrate
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.planners.safe_greedy import SafeGreedyPlanner
from cpp_mujoco.protocol.evaluate import evaluate

TINY = GridMap.from_ascii(["LTT", "TNT", "TTL"], name="tiny")
DT = PhysicsConfig().control_dt  # 0.02 s


def test_low_altitude_parameters_follow_mil_f_8785c():
    h = 6.0 / 0.3048  # ft, the default camera altitude
    for level, knots in (("light", 15), ("moderate", 30), ("severe", 45)):
        p = DrydenParams.low_altitude(level, 6.0)
        sigma_w = 0.1 * knots * 0.514444
        assert p.sigma_w == pytest.approx(sigma_w, rel=1e-5)
        assert p.sigma_u == p.sigma_v == pytest.approx(sigma_w / (0.177 + 0.000823 * h) ** 0.4)
        assert p.length_w == pytest.approx(6.0)
        assert p.length_u == p.length_v == pytest.approx(h / (0.177 + 0.000823 * h) ** 1.2 * 0.3048)
    moderate = DrydenParams.low_altitude("moderate", 6.0)
    assert (round(moderate.sigma_u, 2), round(moderate.length_u, 1)) == (2.98, 43.1)
    low = DrydenParams.low_altitude("light", 1.0)  # below 10 ft: the standard's lowest height
    assert low.length_w == pytest.approx(10 * 0.3048)


def test_the_discretisation_is_exact():
    """Φ = expm(A·dt); the kick keeps the unit stationary covariance; the sampled output has
    the Dryden correlation at every lag (no sampling noise: matrix algebra)."""
    h = np.array([1.0, math.sqrt(3.0)])
    for r in (1e-4, 0.01, 0.2, 0.3, 1.5):  # both branches of the small-r series
        f11, f12, f21, f22, l11, l21, l22 = tb.second_order(r)
        phi = np.array([[f11, f12], [f21, f22]])
        chol = np.array([[l11, 0.0], [l21, l22]])
        assert phi == pytest.approx(expm(np.array([[0.0, 1.0], [-1.0, -2.0]]) * r), abs=1e-14)
        assert phi @ phi.T + chol @ chol.T == pytest.approx(np.eye(2), abs=1e-14)
        power = np.eye(2)
        for k in range(1, 40):
            power = power @ phi
            assert h @ power @ h / 4 == pytest.approx(correlation("w", k * r, 1.0), abs=1e-12)
        decay, kick = tb.first_order(r)
        assert (decay, decay**2 + kick**2) == pytest.approx((math.exp(-r), 1.0), abs=1e-15)
    for x in (1e-6, 1e-3, 0.3, 0.4999, 0.5, 2.0):
        assert tb._tail3(x) == pytest.approx(gammainc(3, x), rel=1e-13)


def sample(params, dt, airspeed, ticks, seed=0):
    """``ticks`` gusts at ``airspeed`` from the flight's own filter kernel, and the airspeed
    its time scales use."""
    turbulence = DrydenTurbulence(params, dt)
    gusts = turbulence.sequence(airspeed, ticks, np.random.default_rng(seed))
    return gusts, turbulence.effective_airspeed(airspeed)


@pytest.mark.parametrize(
    ("dt", "airspeed", "axes"),
    [(DT, 10.0, "w"), (0.1, 25.0, "uv")],
    ids=["control-rate-w", "coarse-uv"],
)
def test_generated_gusts_match_the_model(dt, airspeed, axes):
    """σ within 5 %, the correlation at lag L/V and the fitted scale length within 10 %.
    300k ticks hold ≥ 17 000 scale lengths of the axes checked (sampling scatter over seeds:
    < 1 % on σ, ≤ 3.5 % on ρ, ≤ 2 % on L); u and v need long air paths, so their case samples
    coarsely — the discretisation is exact at any dt (test above)."""
    params = DrydenParams.low_altitude("moderate", 6.0)
    gusts, speed = sample(params, dt, airspeed, 300_000)
    fitted = measure(gusts, dt, speed, params)
    for axis in axes:
        i, length = "uvw".index(axis), params.length(axis)
        assert gusts[:, i].std() == pytest.approx(params.sigma(axis), rel=0.05), axis
        lag = max(1, round(length / (speed * dt)))
        x = gusts[:, i] - gusts[:, i].mean()
        rho = float(x[:-lag] @ x[lag:] / (x @ x) * len(x) / (len(x) - lag))
        assert rho == pytest.approx(correlation(axis, lag * speed * dt, length), rel=0.10), axis
        assert fitted[axis]["length_fit"] == pytest.approx(length, rel=0.10), axis


def test_airspeed_sets_the_time_scale_with_a_floor():
    params = DrydenParams.low_altitude("severe", 6.0)
    slow, _ = sample(params, DT, 0.2, 200, seed=4)  # below MIN_AIRSPEED: held at 1 m/s
    floor, _ = sample(params, DT, tb.MIN_AIRSPEED, 200, seed=4)
    fast, _ = sample(params, DT, 8.0, 200, seed=4)
    assert np.array_equal(slow, floor) and not np.allclose(fast, floor)
    # faster air past the UAV: the w gust decorrelates faster (L_w / V)
    lag1 = [np.corrcoef(g[:-1, 2], g[1:, 2])[0, 1] for g in (floor, fast)]
    assert lag1[0] > lag1[1]


def winds(config: PhysicsConfig, *seeds: int, ticks: int = 300, speed: float = 2.0) -> np.ndarray:
    """The default wind part's output (len(seeds), ticks, 3) for a batch of drones, drone i
    seeded ``seeds[i]``, each flying the same straight eastward line."""
    m, dt = len(seeds), config.control_dt
    wind = Wind(config, dt, m)
    for i, seed in enumerate(seeds):
        wind.reset(i, np.random.default_rng(seed))
    drones = np.arange(m)
    out = [
        wind.velocity(drones, np.full(m, k * dt), np.tile((speed * k * dt, 0.0, 6.0), (m, 1)))
        for k in range(ticks)
    ]
    return np.stack(out, axis=1)


def test_none_is_exactly_the_steady_wind_and_levels_are_seeded():
    calm = PhysicsConfig(wind_speed=4.0, wind_direction=90.0)
    assert Wind(calm, DT).turbulence is None
    assert np.array_equal(winds(calm, 1)[0], np.tile(calm.wind_vector, (300, 1)))
    moderate = PhysicsConfig(wind_speed=4.0, wind_direction=90.0, turbulence="moderate")
    first, again, other = winds(moderate, 1, 1, 2)
    assert np.array_equal(first, again)  # same seed, same gusts
    assert not np.allclose(first, other)  # another seed, other gusts
    assert np.array_equal(first, winds(moderate, 1)[0])  # in a batch as alone
    assert np.all(first.std(axis=0) > 0.01)  # all three components move
    # OU gusts stay available and combine with turbulence, still seeded
    both = PhysicsConfig(gust_std=1.0, turbulence="light")
    first, again, other = winds(both, 3, 3, 4)
    assert np.array_equal(first, again) and not np.allclose(first, other)
    assert np.array_equal(first, winds(both, 3)[0])


def test_the_sampled_gusts_are_the_winds_turbulence():
    """A drone holding still in a steady wind meets the air at the wind's speed every tick: its
    turbulence is :meth:`DrydenTurbulence.sequence` (the sample of the statistics above) from
    the same seed, normal for normal, across blocks of normals."""
    config = PhysicsConfig(wind_speed=4.0, wind_direction=90.0, turbulence="moderate")
    wind = Wind(config, DT)
    wind.reset(0, np.random.default_rng(5))
    ticks, still = 2500, np.array([[1.0, 2.0, 6.0]])
    out = np.array(
        [wind.velocity(np.array([0]), np.array([k * DT]), still)[0] for k in range(ticks)]
    )
    u, v, w = wind.turbulence.sequence(4.0, ticks, np.random.default_rng(5)).T
    (sx, sy, sz), (cx, cy) = config.wind_vector, wind.axis[0]
    expected = np.stack([sx + u * cx - v * cy, sy + u * cy + v * cx, sz + w], axis=1)
    assert out == pytest.approx(expected, abs=1e-12)


def test_u_lies_along_the_steady_wind_and_airspeed_is_relative():
    """Only the u filter is set (to 1) and no noise is drawn: each tick's gust is that filter's
    decay, e^(−V·dt/L_u), at the airspeed V the tick took, read back from the output."""
    config = PhysicsConfig(wind_speed=3.0, wind_direction=90.0, turbulence="light")  # from east
    wind = Wind(config, DT, 2)
    for i in range(2):
        wind.reset(i, np.random.default_rng(i))
    wind.state[:] = (1.0, 0.0, 0.0, 0.0, 0.0)
    wind.turb_noise.block[:] = 0.0
    turbulence, drones = wind.turbulence, np.arange(2)
    sigma_u, length_u = turbulence.params.sigma_u, turbulence.params.length_u
    sx, sy, sz = config.wind_vector  # (-3, 0, 0): blowing west
    # drone 0 flies east at 2 m/s, drone 1 drifts west with the wind
    east, west = np.array([2.0, 0.0, 0.0]), np.array([-3.0, 0.0, 0.0])
    height = np.array([0.0, 0.0, 6.0])
    out = np.array(
        [
            wind.velocity(drones, np.full(2, k * DT), np.stack([east, west]) * k * DT + height)
            for k in range(5)
        ]
    )
    decay = turbulence.coefficients(turbulence.effective_airspeed(3.0))[0]
    assert out[0, 0] == pytest.approx((sx - sigma_u * decay, sy, sz), abs=1e-12)  # along the wind
    assert out[..., 1] == pytest.approx(np.full((5, 2), sy), abs=1e-12)  # nothing across …
    assert np.all(out[..., 2] == sz)  # … nor vertical
    gust = (sx - out[..., 0]) / sigma_u  # u, positive along the wind (westward)
    airspeed = -np.log(gust / np.vstack([np.ones(2), gust[:-1]])) * length_u / DT
    effective = turbulence.effective_airspeed
    # first tick: no velocity yet, the steady wind's speed
    assert airspeed[0] == pytest.approx([effective(3.0)] * 2, rel=1e-9)
    assert airspeed[1:, 0] == pytest.approx([effective(5.0)] * 4, rel=1e-9)  # |(-3) - 2|: adds up
    assert airspeed[1:, 1] == pytest.approx([tb.MIN_AIRSPEED] * 4, rel=1e-9)  # still air: the floor


@pytest.mark.parametrize("value", ["strong", "Moderate", 3, None])
def test_bad_turbulence_option_is_a_value_error_naming_it(value):
    with pytest.raises(ValueError, match="turbulence must be one of 'none', 'light'"):
        gym.make("cpp_mujoco/MuJoCo-v0", map=TINY, turbulence=value)


def test_turbulence_above_the_low_altitude_model_is_rejected():
    with pytest.raises(ValueError, match="turbulence='light'.*1000 ft"):
        PhysicsConfig(altitude=400.0, turbulence="light")
    PhysicsConfig(altitude=400.0)  # without turbulence any altitude flies


def test_the_budget_unit_is_calibrated_in_calm_air_whatever_the_turbulence():
    severe = PhysicsConfig(turbulence="severe")
    assert severe.calibration_key() == PhysicsConfig().calibration_key()
    assert calibrate(severe) == calibrate(PhysicsConfig())


def fly(turbulence: str, seed: int) -> dict:
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=TINY, turbulence=turbulence)
    env.reset(seed=seed, options={"start": (0, 0), "budget": 5})
    for action in (1, 3, 4):  # east, back west, land
        _, _, done, _, info = env.step(action)
    assert done
    return info


def test_a_mujoco_episode_flies_in_moderate_turbulence():
    calm, gusty = fly("none", 0), fly("moderate", 0)
    assert gusty["landed"] and gusty["crash_reason"] is None
    assert math.isfinite(gusty["energy_used_j"]) and gusty["energy_used_j"] > 0
    assert gusty["energy_used_j"] != calm["energy_used_j"]
    assert fly("moderate", 0)["energy_used_j"] == gusty["energy_used_j"]  # seeded
    assert fly("moderate", 1)["energy_used_j"] != gusty["energy_used_j"]


def test_turbulence_flows_through_the_protocol_into_the_conditions():
    run = dict(backend="mujoco", budgets=[4], workers=1)
    calm = evaluate(SafeGreedyPlanner(), TINY, **run)
    gusty = evaluate(SafeGreedyPlanner(), TINY, env_kwargs={"turbulence": "moderate"}, **run)
    assert gusty.conditions["physics_config"]["turbulence"] == "moderate"
    assert calm.conditions["physics_config"]["turbulence"] == "none"
    assert not np.array_equal(gusty.physics["energy_used_j"], calm.physics["energy_used_j"])
