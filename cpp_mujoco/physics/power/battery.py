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

import numpy as np

from cpp_mujoco.physics.power import kernels

# Chen & Rincón-Mora 2006: V_oc(s) = −a·e^(−b·s) + c0 + c1·s + c2·s² + c3·s³ (V per cell)
_A, _B = 1.031, 35.0
_C = (3.685, 0.2156, -0.1178, 0.3201)
# the curve as the kernels take it: a, b, c0…c3, then a/b, c1/2, c2/3
OCV = np.array([_A, _B, *_C, _A / _B, _C[1] / 2, _C[2] / 3])

CUTOFF = "battery voltage under the cut-off: emergency landing where it was"
OVERLOAD = "battery cannot deliver the power: motors cut, the UAV fell"


def cell_ocv(soc: float) -> float:
    """Open-circuit voltage of one cell at state of charge ``soc`` (0..1), V."""
    return kernels.ocv(float(soc), OCV)


def cell_ocv_integral(soc: float) -> float:
    """∫₀^soc V_oc(s) ds (V per unit SOC): the cell's energy per coulomb of capacity."""
    return kernels.ocv_integral(float(soc), OCV)


def pack_current(v_oc: float, resistance: float, power: float) -> float | None:
    """Current (A) at which a source of ``v_oc`` behind ``resistance`` delivers ``power`` W;
    None when it cannot (V_oc² < 4RP)."""
    current = kernels.current_of(float(v_oc), float(resistance), float(power))
    return None if current < 0.0 else current


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
    """The packs of ``n`` drones over their episodes, drawn from once per control tick by the
    compiled :func:`~cpp_mujoco.physics.power.kernels.power` (the load's electrical power in,
    the chemical energy removed out; the motors stop when a pack cannot carry the load, and
    :attr:`failure` says why). :attr:`below_cutoff`: the last tick's terminal voltage sagged
    under the cut-off. ``drawn_j = load_j + loss_j`` holds to rounding: the three are
    accumulated from the same current."""

    def __init__(self, spec: PackSpec, n: int):
        self.spec = spec
        self.charge_c = np.full(n, math.inf)  # coulombs per unit SOC
        self.soc = np.full(n, spec.reference_soc)
        self.current = np.zeros(n)
        self.drawn_j, self.load_j, self.loss_j = np.zeros(n), np.zeros(n), np.zeros(n)
        self.below_cutoff = np.zeros(n, dtype=bool)
        self.failure = np.full(n, None, dtype=object)
        self.f_soc = np.array([cell_ocv_integral(s) for s in self.soc])  # F(soc), the next f0

    def reset(self, i: int, capacity_j: float) -> None:
        """Pack ``i`` is fresh, holding ``capacity_j`` J of drawable energy (SOC 1 → reserve);
        an unlimited one (inf) sits at ``reference_soc``."""
        s = self.spec
        if math.isinf(capacity_j):
            self.charge_c[i], self.soc[i] = math.inf, s.reference_soc
        else:
            window = cell_ocv_integral(1.0) - cell_ocv_integral(s.reserve)
            self.charge_c[i], self.soc[i] = capacity_j / (s.cells * window), 1.0
        self.current[i] = 0.0
        self.drawn_j[i] = self.load_j[i] = self.loss_j[i] = 0.0
        self.below_cutoff[i], self.failure[i] = False, None
        self.f_soc[i] = cell_ocv_integral(self.soc[i])

    def ocv(self) -> np.ndarray:
        """Open-circuit voltage of each pack now, V."""
        return self.spec.cells * np.array([cell_ocv(s) for s in self.soc])

    def voltage(self) -> np.ndarray:
        """Terminal voltage of each pack at its last tick's current, V."""
        return self.ocv() - self.current * self.spec.resistance
