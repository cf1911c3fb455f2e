"""Rotor power in forward flight: still-air hover unchanged, Glauert solved, the power curve's
bucket, hover in wind, the tick-rate integral against the per-physics-step one, bookkeeping."""

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.grid.actions import NORTH, SOUTH
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.action import HOVER, MOVE
from cpp_mujoco.physics.calibration import _airframe, unit_energy
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.flight import Flight
from cpp_mujoco.physics.kernel_constants import control_constants
from cpp_mujoco.physics.power import kernels
from cpp_mujoco.physics.power.rotor import ForwardFlightPower, PowerModel, level_flight_power

GRID = GridMap.from_ascii(["GGG", "GGG", "GGG"], name="power")
RHO = 1.225


@pytest.fixture(scope="module")
def params():
    return _airframe()


@pytest.fixture(scope="module")
def model(params):
    return ForwardFlightPower(params, RHO)


def make_flight(**kw) -> Flight:
    """One drone over the 3×3 grid hovering over its centre (cell 4), forward-flight power
    unless ``kw`` says otherwise, an unlimited pack."""
    config = PhysicsConfig(**{"power_model": "forward-flight", **kw})
    flight = Flight.alone(GRID, config)
    flight.reset(0, 1, 1, math.inf, np.random.default_rng(0))
    return flight


def test_still_air_power_equals_the_calibrated_hover(params, model):
    hover = PowerModel(params, RHO)
    weight = [params.weight / 4] * 4
    assert model.power(weight, (0.0, 0.0, 0.0)) == pytest.approx(158.0, rel=0.01)
    for t in (0.5, 2.0, params.weight / 4, 7.5):  # both scale as T^1.5 in still air
        assert model.power([t] * 4, (0, 0, 0)) == pytest.approx(hover.power([t] * 4), rel=1e-12)


def test_glauert_induced_velocity_solves_its_relation(model):
    worst = 0.0
    for t in (0.3, 3.7, 8.0):
        vh2 = t * model.inv_2rho_a
        for v_par in (0.05, 1.0, 4.0, 12.0, 30.0):
            for v_perp in (-0.45 * math.sqrt(vh2), -0.5, 0.0, 1.0, 6.0):
                v = model.induced_velocity(t, v_par, v_perp)
                residual = v * math.sqrt(v_par**2 + (v_perp + v) ** 2) - vh2
                worst = max(worst, abs(residual) / vh2)
    assert worst < 1e-9
    # the high-speed limit: v_i → T / (2ρA·V)
    assert model.induced_velocity(3.7, 40.0, 0.0) == pytest.approx(
        3.7 * model.inv_2rho_a / 40.0, rel=0.01
    )
    # vortex-ring guard: any faster axial descent is taken at −vrs_limit·v_h
    vh = math.sqrt(3.7 * model.inv_2rho_a)
    f = model.constants()
    assert kernels.ratio(3.7, 0.0, -5 * vh, f) == kernels.ratio(3.7, 0.0, -model.vrs * vh, f) > 0


def test_level_flight_power_curve_is_a_bucket(params, model):
    curve = [level_flight_power(model, params, RHO, v)["power_w"] for v in range(16)]
    hover = curve[0]
    best = int(np.argmin(curve))
    assert 4 <= best <= 9  # minimum power at a moderate airspeed …
    assert curve[6] < 0.95 * hover  # translational lift: below hover …
    assert curve[15] > 1.5 * hover  # … and the drag's V³ takes over at high airspeed
    assert all(b > a for a, b in zip(curve[best:], curve[best + 1 :], strict=False))
    # the momentum model is airspeed-blind apart from the thrust: it has no bucket
    momentum = PowerModel(params, RHO)
    drag = [0.5 * RHO * params.drag_area * v * v for v in range(16)]
    blind = [momentum.power([math.hypot(params.weight, d) / 4] * 4) for d in drag]
    assert min(blind) == blind[0]


def test_hover_in_wind_costs_less_at_6_and_more_at_11_m_s():
    power = {}
    for wind in (0.0, 6.0, 11.0):
        f = make_flight(wind_speed=wind)
        f.fly_one(HOVER, 4)  # lean into the wind first
        result = f.fly_one(HOVER, 4)
        assert result.failure is None
        power[wind] = result.energy / result.duration
    assert power[6.0] < 0.95 * power[0.0]
    assert power[11.0] > power[6.0]
    assert power[11.0] > power[0.0]


def test_calm_hover_flight_unchanged_by_the_forward_flight_model():
    energy = {}
    for name in ("momentum", "forward-flight"):
        f = make_flight(power_model=name)
        energy[name] = f.fly_one(HOVER, 4).energy
    assert energy["forward-flight"] == pytest.approx(energy["momentum"], rel=0.01)


def test_upwind_legs_cost_far_more_than_downwind_legs():
    f = make_flight(wind_speed=12.0)  # from the north
    f.fly_one(HOVER, 4)
    up = f.fly_one(MOVE, 1)  # north, into the wind
    f.fly_one(HOVER, 1)
    down = f.fly_one(MOVE, 4)
    assert up.arrived and down.arrived
    assert up.energy > 1.3 * down.energy
    calm = make_flight()
    out_and_back = calm.fly_one(MOVE, 1).energy + calm.fly_one(MOVE, 4).energy
    assert up.energy + down.energy > 1.2 * out_and_back


def body_air(flight: Flight, data: mujoco.MjData | None = None) -> np.ndarray:
    """Drone 0's velocity relative to the wind of its last tick, in the body frame: from
    ``data`` when given, else from its state row."""
    q, v, _ = flight.cols
    qpos, qvel = (
        (data.qpos, data.qvel) if data is not None else (flight.state[0, q], flight.state[0, v])
    )
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, np.asarray(qpos[3:7], dtype=float))
    return rotation.reshape(3, 3).T @ (np.asarray(qvel[:3]) - flight.wind_now[0])


class PerStep:
    """Wraps drone 0's physics steps: each control interval's energy from the tick's closed form
    (the kernel :func:`~cpp_mujoco.physics.power.kernels._energy` on the interval's first
    state), and on the side the forward-flight power at every physics step's own state (thrust,
    attitude, velocity) of a copy of the drone stepped by ``mujoco.mj_step``, times the step."""

    def __init__(self, flight: Flight):
        self.flight, self.batch_step = flight, flight._step
        energy = flight.energy_of
        self.model = energy.forward
        self.c = control_constants(flight.dt, energy=energy)
        self.ff = self.model.constants()
        self.side = mujoco.MjData(flight.model)
        self.ticks, self.steps = [], 0.0

    def __call__(self, drones: np.ndarray, nstep: int) -> None:
        f, d = self.flight, self.side
        if 0 in drones.tolist() and f.motors_on[0]:
            _, _, a = f.cols
            act, ctrl = f.state[0, a], f.state[0, f.ctrl_cols]
            air = body_air(f)
            e = f.energy_of
            self.ticks.append(kernels._energy(act, ctrl, *air, self.c, e.decay, self.ff))
            f.copy_data(0, d)
            assert np.array_equal(d.ctrl, ctrl)  # the tick's command, held over the interval
            for _ in range(nstep):
                power = self.model.power(d.act.tolist(), body_air(f, d))
                self.steps += power * f.model.opt.timestep
                mujoco.mj_step(f.model, d)
        self.batch_step(drones, nstep)


@pytest.mark.parametrize("wind", [0.0, 9.0])
def test_tick_rate_energy_matches_the_per_physics_step_integral(wind):
    f = make_flight(wind_speed=wind)  # from the north: the first move flies into it
    f.fly_one(HOVER, 4)  # settle into the wind, not measured
    f._step = per_step = PerStep(f)
    load = f.battery.load_j[0]
    for cell in (1, 4):  # north into the wind, then back south
        assert f.fly_one(MOVE, cell).arrived
    assert len(per_step.ticks) > 200
    assert sum(per_step.ticks) == pytest.approx(per_step.steps, rel=1e-4)  # measured: 4e-5 at 9 m/s
    # the flight's load is the kernel's energy of its ticks, nothing else
    assert f.battery.load_j[0] - load == pytest.approx(sum(per_step.ticks), rel=1e-12)


def test_energy_used_is_the_sum_of_the_ticks():
    env = gym.make(
        "cpp_mujoco/MuJoCo-v0", map=GRID, wind_speed=6.0, power_model="forward-flight"
    ).unwrapped
    env.reset(seed=0, options={"start": (2, 1), "budget": 10})
    pack = env.flight.battery
    for action in (NORTH, NORTH, SOUTH):
        _, _, terminated, truncated, info = env.step(action)
        assert not (terminated or truncated)
        # every tick's draw from the pack, its I²R loss included, and nothing else
        assert info["energy_used_j"] == pytest.approx(pack.drawn_j[0], rel=1e-12)
        assert pack.drawn_j[0] == pytest.approx(pack.load_j[0] + pack.loss_j[0], rel=1e-6)
    env.close()


def test_power_model_option_is_checked():
    with pytest.raises(ValueError, match="power_model"):
        PhysicsConfig(power_model="helicopter")


def test_a_move_costs_most_upwind_least_downwind_alike_from_every_direction():
    """The per-action energy table's figures (``scripts/transfer.py``): in a steady 9 m/s wind
    the airframe pays for the headwind leg; turning the wind by 90° turns nothing else."""
    from cpp_mujoco.physics.action_energy import action_energy

    north = action_energy(PhysicsConfig(wind_speed=9.0, wind_direction=0.0))
    east = action_energy(PhysicsConfig(wind_speed=9.0, wind_direction=90.0))
    up, cross, down = (north.mean_j[k] for k in ("upwind", "crosswind", "downwind"))
    assert up > 1.08 * cross and cross > 1.05 * down
    assert north.samples == {"upwind": 2, "downwind": 2, "crosswind": 4, "hover": 1, "land": 1}
    for kind, joules in north.mean_j.items():
        assert east.mean_j[kind] == pytest.approx(joules, rel=0.01), kind
    calm = action_energy(PhysicsConfig())
    assert set(calm.mean_j) == {"crosswind", "hover", "land"}  # no wind to face
    assert calm.mean_j["crosswind"] == pytest.approx(unit_energy(PhysicsConfig()), rel=0.05)
    assert calm.mean_j["land"] < calm.mean_j["crosswind"]  # a landing costs less than a unit
