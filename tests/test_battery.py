"""The LiPo pack: OCV curve, I²R loss, energy conservation with the rotors, cut-off, info and
recording, and the calm-air budget unit it leaves intact."""

import math

import mujoco
import numpy as np
import pytest
from scipy.integrate import quad

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.grid.actions import NORTH, SOUTH
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.action import HOVER
from cpp_mujoco.physics.calibration import calibration, hover_power
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.envs.single import MuJoCoEnv
from cpp_mujoco.physics.flight import Flight
from cpp_mujoco.physics.power.battery import (
    CUTOFF,
    OCV,
    OVERLOAD,
    Battery,
    PackSpec,
    cell_ocv,
    cell_ocv_integral,
    pack_current,
)
from cpp_mujoco.physics.power.kernels import _draw
from cpp_mujoco.physics.quadrotor import QuadrotorParams, quadrotor_xml
from cpp_mujoco.review.recording import MissionRecorder
from tests.test_review import rrd_entities

OPEN = GridMap.from_ascii(["TTTTT", "TTTTT", "TTLTT", "TTTTT", "TTTTT"], name="open")
SPEC = PackSpec()


# ----------------------------------------------------------------------------- the pack alone
def test_ocv_is_monotone_in_soc_and_its_integral_is_exact():
    soc = np.linspace(0.0, 1.0, 20001)
    v = np.array([cell_ocv(s) for s in soc])
    assert np.all(np.diff(v) > 0)
    assert v[0] == pytest.approx(2.654, abs=1e-3) and v[-1] == pytest.approx(4.1029, abs=1e-4)
    for s in (0.05, 0.3, 1.0):
        assert cell_ocv_integral(s) == pytest.approx(quad(cell_ocv, 0.0, s)[0], rel=1e-12)


def draw(pack: Battery, power: float, dt: float = 0.02) -> tuple[float, bool]:
    """Pack 0 carries ``power`` W for ``dt`` s through the kernel the flight's tick calls:
    (chemical J removed, whether the pack could carry the load)."""
    s = pack.spec
    return _draw(0, power, dt, float(s.cells), s.resistance, s.cutoff_v, OCV, pack.charge_c,
                 pack.soc, pack.current, pack.drawn_j, pack.load_j, pack.loss_j,
                 pack.below_cutoff, pack.f_soc)  # fmt: skip


def set_soc(pack: Battery, soc: float) -> None:
    """Pack 0 at state of charge ``soc``, with the OCV integral the kernel starts from."""
    pack.soc[0], pack.f_soc[0] = soc, cell_ocv_integral(soc)


def test_higher_power_wastes_a_larger_fraction():
    fractions = []
    for power in (50.0, 150.0, 300.0, 450.0):
        pack = Battery(SPEC, 1)  # unlimited pack, held at the reference SOC
        chem, ok = draw(pack, power)
        assert ok and pack.soc[0] == SPEC.reference_soc
        assert chem == pytest.approx(pack.load_j[0] + pack.loss_j[0], rel=1e-12)
        assert pack.load_j[0] == pytest.approx(power * 0.02, rel=1e-12)
        assert pack.voltage()[0] == pytest.approx(pack.ocv()[0] - pack.current[0] * SPEC.resistance)
        # the terminal voltage times the current is the load: the smaller root of V·I − I²R = P
        assert pack.voltage()[0] * pack.current[0] == pytest.approx(power, rel=1e-12)
        fractions.append(pack.loss_j[0] / pack.load_j[0])
    assert all(b > 1.5 * a for a, b in zip(fractions, fractions[1:], strict=False))
    # the closed form: loss / load = I·R / (V_oc − I·R)
    v_oc = pack.ocv()[0]
    i = pack_current(v_oc, SPEC.resistance, 450.0)
    assert fractions[-1] == pytest.approx(i * SPEC.resistance / (v_oc - i * SPEC.resistance))


def test_a_load_the_pack_cannot_deliver_is_a_battery_failure():
    # V_oc²/4R ≈ 21.9 W at the reference SOC; no cut-off, so only the overload can stop it
    weak = PackSpec(cell_resistance=0.5, cutoff_v=0.0)
    pack = Battery(weak, 1)
    chem, ok = draw(pack, 21.0)
    assert ok and math.isfinite(chem)
    drawn, soc = pack.drawn_j[0], pack.soc[0]
    chem, ok = draw(pack, 23.0)
    assert not ok and math.isnan(chem)
    assert (pack.drawn_j[0], pack.soc[0]) == (drawn, soc)  # nothing is drawn
    # in flight the tick marks the pack's failure, the motors stop and the UAV falls
    config = PhysicsConfig(battery_cell_resistance=0.5, battery_cutoff_v=0.0)
    flight = Flight.alone(OPEN, config)
    flight.reset(0, 2, 2, math.inf, np.random.default_rng(0))
    result = flight.fly_one(HOVER, 12)
    assert result.failure == OVERLOAD and flight.battery.failure[0] == OVERLOAD
    assert not flight.motors_on[0] and not result.landed
    # the cut-off is a failsafe signal, not a failure: the sag (V_oc/2 at the maximum power)
    # is flagged, and the pack still delivers
    pack = Battery(SPEC, 1)
    v_oc = pack.ocv()[0]
    chem, ok = draw(pack, 0.1 * v_oc**2 / (4 * SPEC.resistance))
    assert ok and math.isfinite(chem)
    assert not pack.below_cutoff[0]
    chem, ok = draw(pack, 0.99 * v_oc**2 / (4 * SPEC.resistance))
    assert ok and math.isfinite(chem)
    assert pack.below_cutoff[0] and pack.failure[0] is None
    assert pack_current(10.0, 1.0, 25.0) == pytest.approx(5.0)  # the double root
    assert pack_current(10.0, 1.0, 25.0001) is None


def test_defaults_leave_the_cut_off_to_overload_not_to_a_calm_budget():
    """Why the reserve: at the defaults the sag at full thrust stays above the cut-off down to
    the reserve, so a flight that keeps to its budget never trips it; a full pack sags less."""
    model = mujoco.MjModel.from_xml_path(str(quadrotor_xml()))
    params = QuadrotorParams.from_model(model, prefix="")
    full_throttle = hover_power(PhysicsConfig()) * params.thrust_to_weight**1.5
    pack = Battery(SPEC, 1)
    pack.reset(0, 1000.0)
    set_soc(pack, SPEC.reserve)
    chem, ok = draw(pack, full_throttle)
    assert ok and math.isfinite(chem)
    assert pack.voltage()[0] > SPEC.cells * SPEC.cutoff_v
    assert not pack.below_cutoff[0]  # the flag the failsafe reads


def test_a_calm_move_costs_the_same_unit_across_the_soc_window():
    """The unit is measured at the window's middle; at either end a hover-power load draws
    within a quarter of the unit margin of it."""
    load = hover_power(PhysicsConfig())
    per_soc = {}
    for soc in (1.0, SPEC.reference_soc, SPEC.reserve):
        pack = Battery(SPEC, 1)
        set_soc(pack, soc)
        per_soc[soc], ok = draw(pack, load)
        assert ok
    mid = per_soc[SPEC.reference_soc]
    margin = PhysicsConfig().unit_margin
    assert per_soc[1.0] < mid < per_soc[SPEC.reserve]
    assert abs(per_soc[1.0] / mid - 1) < margin / 4
    assert abs(per_soc[SPEC.reserve] / mid - 1) < margin / 4


def test_bad_battery_options_are_one_line_errors():
    with pytest.raises(ValueError, match="battery_cells must be a whole number"):
        MuJoCoEnv(map=OPEN, battery_cells=2.5)
    with pytest.raises(ValueError, match="battery_reserve must be in"):
        PhysicsConfig(battery_reserve=1.0)
    with pytest.raises(ValueError, match="battery_cutoff_v is out of range"):
        PackSpec(cutoff_v=4.2)


# ----------------------------------------------------------------------------- a flown episode
@pytest.fixture(scope="module")
def episode():
    """A calm episode on a 5×5 map flown until its budget is spent, and the info after each
    step."""
    env = MuJoCoEnv(map=OPEN, wind_speed=3.0, wind_direction=40.0)  # some variety in the load
    _, info = env.reset(seed=0, options={"start": (2, 2), "budget": 4})
    infos = [info]
    terminated = False
    actions = iter([NORTH, SOUTH] * 10)
    while not terminated:
        _, _, terminated, _, info = env.step(next(actions))
        infos.append(info)
    return env, infos


def test_energy_conservation_between_the_battery_and_the_rotors(episode):
    env, infos = episode
    pack = env.flight.battery
    load, drawn, loss = pack.load_j[0], pack.drawn_j[0], pack.loss_j[0]
    assert drawn == pytest.approx(infos[-1]["energy_used_j"], rel=1e-12)  # the budget's energy
    assert drawn == pytest.approx(load + loss, rel=1e-6)
    assert 0.005 < loss / load < 0.05  # I²R: a few percent at these loads
    # the chemical energy equals the charge removed times the cited OCV, integrated afresh
    cells, q = pack.spec.cells, pack.charge_c[0]
    chemical = cells * q * quad(cell_ocv, pack.soc[0], 1.0, points=[0.1], limit=200)[0]
    assert drawn == pytest.approx(chemical, rel=1e-6)
    assert infos[-1]["crashed"] and infos[-1]["budget"] == 0  # ran the budget down


def test_info_reports_the_pack_in_range_over_an_episode(episode):
    env, infos = episode
    spec = env.flight.battery.spec
    soc = [i["state_of_charge"] for i in infos]
    volts = [i["battery_voltage_v"] for i in infos]
    assert soc[0] == 1.0 and volts[0] == pytest.approx(spec.cells * cell_ocv(1.0))
    assert all(0.0 <= s <= 1.0 for s in soc)
    assert all(b <= a for a, b in zip(soc, soc[1:], strict=False))
    assert all(spec.cells * spec.cutoff_v < v <= spec.cells * cell_ocv(1.0) for v in volts)
    # the budget's energy spans SOC 1 → reserve: what is left above the reserve is exactly
    # the energy the budget has left, less than the one unit that no longer reads as a unit
    pack, last = env.flight.battery, infos[-1]
    above_reserve = spec.cells * pack.charge_c[0] * quad(cell_ocv, spec.reserve, soc[-1])[0]
    left = 4 * env.unit_energy - last["energy_used_j"]
    assert above_reserve == pytest.approx(left, rel=1e-6)
    assert 0 < left < env.unit_energy
    assert spec.reserve < soc[-1] < spec.reserve + (1 - spec.reserve) / 4


def test_calm_unit_is_energy_drawn_from_the_pack():
    """The calibration flies through the pack: its unit includes the I²R loss (≈ 1.9 % at the
    default 5 mΩ per cell), and without resistance it is the rotors' energy alone."""
    ideal = calibration(PhysicsConfig(battery_cell_resistance=0.0))["unit_energy_j"]
    real = calibration(PhysicsConfig())["unit_energy_j"]
    assert 1.01 < real / ideal < 1.03


def test_cut_off_lands_where_the_uav_is_and_ends_as_a_battery_crash():
    # 3.95 V per cell under load is reached near SOC 0.85: within the first units of the budget
    env = MuJoCoEnv(map=OPEN, battery_cutoff_v=3.95)
    _, info = env.reset(seed=0, options={"start": (2, 2), "budget": 10})
    terminated, steps = False, 0
    while not terminated:
        _, _, terminated, _, info = env.step((NORTH, SOUTH)[steps % 2])
        steps += 1
    assert info["crashed"] and info["crash_reason"] == CUTOFF
    assert info["crash_reason"].startswith("battery")
    assert not info["landed"]
    flight = env.flight
    assert flight._ground_contact(0) is True  # on its skids: the failsafe landed it, upright
    assert flight.nfz_violations[0] == 0
    assert info["budget"] > 0  # the voltage ended it, not the budget
    assert 0.7 < info["state_of_charge"] < 0.95
    assert steps < 10


def test_recording_holds_state_of_charge_and_voltage(tmp_path, episode):
    env, infos = episode
    path = tmp_path / "battery.rrd"
    rec = MissionRecorder(path, OPEN)
    for step, info in enumerate(infos[1:], start=1):
        rec.log_step(3.0 * step, NORTH, -0.2, info, np.zeros(25, bool), 12)
    rec.close()
    entities = rrd_entities(path)
    assert "Scalars" in entities["/metrics/state_of_charge"]
    assert "Scalars" in entities["/metrics/battery_voltage_v"]
    # a grid mission's info has no battery: its recording gets no battery series
    grid = tmp_path / "grid.rrd"
    rec = MissionRecorder(grid, OPEN)
    info = {k: v for k, v in infos[1].items() if k not in ("state_of_charge", "battery_voltage_v")}
    rec.log_step(3.0, NORTH, -0.2, info, np.zeros(25, bool), 12)
    rec.close()
    assert not {"/metrics/state_of_charge", "/metrics/battery_voltage_v"} & set(rrd_entities(grid))
