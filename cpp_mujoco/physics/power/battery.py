"""A LiPo pack between the rotors and the budget: open-circuit voltage, internal resistance,
cut-off failsafe.

Why: the budget is energy drawn from the pack, and a pack does not hand out its energy at the
same price at every load. With open-circuit voltage V_oc(SOC) and a series resistance R, a load
of P watts draws the current I = (V_oc − √(V_oc² − 4RP)) / (2R) (the smaller root of
V_oc·I − I²R = P); the chemical energy removed is V_oc·I·dt = P·dt + I²R·dt, so the fraction
lost in the pack, I·R / V_oc, grows with the load. The terminal voltage V_oc − I·R sags under
load; below the cut-off the autopilot's battery failsafe lands where the UAV is (the flight
reads :attr:`Battery.below_cutoff`; the pack keeps delivering, as a real one does), and a load
above V_oc² / 4R cannot be delivered at all: then the motors stop.

Budget semantics: an episode's pack holds exactly its budget of drawable energy between full
charge (SOC 1) and ``reserve``; the capacity in coulombs follows from that energy, while the
electrical behaviour (OCV curve, cells, resistance) is that of the airframe's pack. A budget of
b units therefore always spans the same SOC window, and a calm move costs the same share of it.
An unlimited pack (``capacity = inf``, the calibration flight) is held at ``reference_soc``, the
middle of that window by charge, where the budget unit is measured.

OCV: Chen & Rincón-Mora (IEEE Trans. Energy Conversion 21(2), 2006, eq. for the TCL PL-383562
polymer Li-ion cell); its closed-form integral gives the exact chemical energy of a tick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# Chen & Rincón-Mora 2006: V_oc(s) = −a·e^(−b·s) + c0 + c1·s + c2·s² + c3·s³ (V per cell)
_A, _B = 1.031, 35.0
_C = (3.685, 0.2156, -0.1178, 0.3201)

CUTOFF = "battery voltage under the cut-off: emergency landing where it was"
OVERLOAD = "battery cannot deliver the power: motors cut, the UAV fell"


def cell_ocv(soc: float) -> float:
    """Open-circuit voltage of one cell at state of charge ``soc`` (0..1), V."""
    c0, c1, c2, c3 = _C
    return -_A * math.exp(-_B * soc) + c0 + soc * (c1 + soc * (c2 + soc * c3))


def cell_ocv_integral(soc: float) -> float:
    """∫₀^soc V_oc(s) ds (V per unit SOC): the cell's energy per coulomb of capacity."""
    c0, c1, c2, c3 = _C
    s = soc
    return _A / _B * (math.exp(-_B * s) - 1.0) + s * (c0 + s * (c1 / 2 + s * (c2 / 3 + s * c3 / 4)))


def pack_current(v_oc: float, resistance: float, power: float) -> float | None:
    """Current (A) at which a source of ``v_oc`` behind ``resistance`` delivers ``power`` W;
    None when it cannot (V_oc² < 4RP). The smaller root, written cancellation-free."""
    if power <= 0.0:
        return 0.0
    disc = v_oc * v_oc - 4.0 * resistance * power
    if disc < 0.0:
        return None
    return 2.0 * power / (v_oc + math.sqrt(disc))


@dataclass(frozen=True)
class PackSpec:
    """The pack's electrical build; see ``assets/README.md`` (battery) for the sources."""

    cells: int = 3  # in series (3S: the airframe's 2212/920 kV motors and thrust tables)
    cell_resistance: float = 0.005  # Ω per cell (PX4's BAT_R_INTERNAL default)
    cutoff_v: float = 3.3  # V per cell under load (ArduPilot's LiPo critical voltage)
    reserve: float = 0.1  # SOC left when the budget is spent (before the OCV knee)

    def __post_init__(self) -> None:
        if isinstance(self.cells, bool) or float(self.cells) != int(self.cells) or self.cells < 1:
            raise ValueError(f"battery_cells must be a whole number >= 1, got {self.cells!r}")
        object.__setattr__(self, "cells", int(self.cells))
        for name, ok in (
            ("battery_cell_resistance", self.cell_resistance >= 0.0),
            ("battery_cutoff_v", 0.0 <= self.cutoff_v < cell_ocv(1.0)),
            ("battery_reserve", 0.0 <= self.reserve < 1.0),
        ):
            if not ok:
                value = getattr(self, name.removeprefix("battery_"))
                raise ValueError(f"{name} is out of range, got {value!r}")

    @classmethod
    def from_config(cls, config) -> PackSpec:
        """From a :class:`~cpp_mujoco.physics.config.PhysicsConfig`'s ``battery_*`` fields."""
        return cls(
            cells=config.battery_cells,
            cell_resistance=config.battery_cell_resistance,
            cutoff_v=config.battery_cutoff_v,
            reserve=config.battery_reserve,
        )

    @property
    def resistance(self) -> float:
        return self.cells * self.cell_resistance

    @property
    def reference_soc(self) -> float:
        """Where an unlimited pack sits: the middle of the budget's SOC window."""
        return 0.5 * (1.0 + self.reserve)


class Battery:
    """The pack's state over one episode, integrated once per control tick.

    ``draw(power, dt)`` takes the load's electrical power (W, whatever model computes it) and
    returns the chemical energy removed (J), or None when the pack cannot carry the load (then
    :attr:`failure` says why and nothing is drawn). :attr:`below_cutoff` says whether the last
    tick's terminal voltage sagged under the cut-off. ``drawn_j = load_j + loss_j`` holds to
    rounding: the three are accumulated from the same current.
    """

    def __init__(self, spec: PackSpec):
        self.spec = spec
        self.reset(math.inf)

    def reset(self, capacity_j: float) -> None:
        """A fresh pack holding ``capacity_j`` J of drawable energy (SOC 1 → reserve)."""
        s = self.spec
        if math.isinf(capacity_j):
            self.charge_c = math.inf  # coulombs per unit SOC
            self.soc = s.reference_soc
        else:
            window = cell_ocv_integral(1.0) - cell_ocv_integral(s.reserve)
            self.charge_c = capacity_j / (s.cells * window)
            self.soc = 1.0
        self.current = 0.0
        self.drawn_j = self.load_j = self.loss_j = 0.0
        self.failure: str | None = None
        self.below_cutoff = False

    @property
    def ocv(self) -> float:
        """Open-circuit voltage of the pack now, V."""
        return self.spec.cells * cell_ocv(self.soc)

    @property
    def voltage(self) -> float:
        """Terminal voltage at the last tick's current, V."""
        return self.ocv - self.current * self.spec.resistance

    def draw(self, power: float, dt: float) -> float | None:
        """Carry ``power`` W for ``dt`` s; chemical J removed, or None (see :attr:`failure`)."""
        s = self.spec
        n, r, q, s0 = s.cells, s.resistance, self.charge_c, self.soc
        v = n * cell_ocv(s0)
        current = pack_current(v, r, power)
        if current is None:
            self.failure = OVERLOAD
            return None
        s1 = s0
        # the OCV averaged over the tick's charge (exact ∫V_oc dq); one or two fixed-point
        # passes converge to rounding, as a tick moves the SOC by well under 1e-3
        for _ in range(3):
            if math.isinf(q) or current == 0.0:
                break
            s1 = s0 - current * dt / q
            v = n * (cell_ocv_integral(s0) - cell_ocv_integral(s1)) / (s0 - s1)
            current = pack_current(v, r, power)
            if current is None:
                self.failure = OVERLOAD
                return None
        if not math.isinf(q) and current > 0.0:
            s1 = s0 - current * dt / q
            v = n * (cell_ocv_integral(s0) - cell_ocv_integral(s1)) / (s0 - s1)
        loss = current * current * r * dt
        chem = v * current * dt  # = n·q·(F(s0) − F(s1)) exactly, = load + loss to rounding
        self.soc = max(s1, 0.0)
        self.current = current
        self.below_cutoff = v - current * r < n * s.cutoff_v
        self.drawn_j += chem
        self.load_j += power * dt if power > 0.0 else 0.0
        self.loss_j += loss
        return chem

    def idle(self) -> None:
        """No load any more (motors cut or landed): the terminal voltage recovers to V_oc."""
        self.current = 0.0
