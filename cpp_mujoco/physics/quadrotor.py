"""The quadrotor's physical parameters, read back from the compiled MJCF (the single source).

Rigid-body and actuator numbers come from MuJoCo's own compiled arrays; what MuJoCo does not model
(rotor disk radius, electrical efficiency, avionics draw, drag area) sits in the MJCF's
``<custom><numeric>`` block. See ``assets/README.md`` for where every number comes from.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from cpp_mujoco.util.resources import bundled_dir

ROTORS = ("fl", "fr", "rr", "rl")  # actuator order in the MJCF


def quadrotor_xml() -> Path:
    """Path of the bundled quadrotor MJCF."""
    return bundled_dir("assets") / "quadrotor.xml"


@dataclass(frozen=True)
class QuadrotorParams:
    """What the controller and the energy model need to know about the airframe."""

    body_id: int  # the rigid body carrying everything (``core``)
    mass: float  # kg, whole vehicle
    inertia: tuple[float, float, float]  # kg·m², principal moments about the body axes
    rotor_xy: np.ndarray  # (4, 2) rotor hub positions in the body frame, m
    yaw_coef: np.ndarray  # (4,) reaction torque per newton of thrust (signed), m
    max_thrust: float  # N per rotor (actuator ctrlrange upper bound)
    motor_tau: float  # s, first-order motor lag (actuator dynprm[0])
    rotor_radius: float  # m, propeller radius (momentum-theory disk)
    power_efficiency: float  # electrical → ideal induced power (figure of merit × motor × ESC)
    avionics_power: float  # W, constant draw of flight controller, radio, camera
    drag_area: float  # m², drag coefficient × reference area of the body

    @classmethod
    def from_model(cls, model: mujoco.MjModel, prefix: str = "quadrotor/") -> QuadrotorParams:
        body = model.body(f"{prefix}core")
        act_ids = [model.actuator(f"{prefix}thrust_{r}").id for r in ROTORS]
        site_ids = model.actuator_trnid[act_ids, 0]
        if not np.all(model.site_bodyid[site_ids] == body.id):
            raise ValueError("every rotor site must sit on the core body")

        def numeric(name: str) -> float:
            return float(model.numeric(f"{prefix}{name}").data[0])

        return cls(
            body_id=int(body.id),
            mass=float(model.body_subtreemass[body.id]),
            inertia=tuple(float(v) for v in model.body_inertia[body.id]),
            rotor_xy=model.site_pos[site_ids, :2].copy(),
            yaw_coef=model.actuator_gear[act_ids, 5].copy(),
            max_thrust=float(model.actuator_ctrlrange[act_ids, 1].min()),
            motor_tau=float(model.actuator_dynprm[act_ids[0], 0]),
            rotor_radius=numeric("rotor_radius"),
            power_efficiency=numeric("power_efficiency"),
            avionics_power=numeric("avionics_power"),
            drag_area=numeric("drag_area"),
        )

    @property
    def weight(self) -> float:
        return self.mass * 9.81

    @property
    def thrust_to_weight(self) -> float:
        return 4 * self.max_thrust / self.weight

    def allocation_matrix(self) -> np.ndarray:
        """(4, 4) map from rotor thrusts to [total thrust, roll, pitch, yaw torque] (body frame).

        A thrust f along body z at (x, y) gives torque (y·f, −x·f, 0) plus the reaction torque
        yaw_coef·f about z.
        """
        x, y = self.rotor_xy[:, 0], self.rotor_xy[:, 1]
        return np.stack([np.ones(4), y, -x, self.yaw_coef])
