"""The flight loop: one grid action flown as a macro-step of controller ticks and MuJoCo steps.

Parts: the vehicle is the compiled model; the controller and the wind are swappable
(:mod:`cpp_mujoco.physics.parts`); the coverage sensor
(:class:`~cpp_mujoco.physics.sensing.camera.CoverageCamera`) and the energy model are the flight's own.

Rates: MuJoCo steps every ``timestep``; the controller, wind, drag, energy and failure checks run
every ``substeps`` physics steps (``mj_step(..., nstep=k)``); the camera takes a frame at
``camera_rate`` plus one at the start and end of every action. Energy is the sum over physics
steps of the thrust's power, scaled per tick by the forward-flight factor of the tick's airspeed
(see :class:`~cpp_mujoco.physics.power.rotor.IntervalEnergy`); no-fly violations are
sampled per tick and counted as ``substeps`` physics steps each.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np

from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.air.wind import QuadraticDrag, Wind
from cpp_mujoco.physics.batched_action import ActionResult
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.control.controller import GeometricController, MinJerk
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.physics.parts import Controller, WindModel
from cpp_mujoco.physics.power.battery import CUTOFF, Battery, PackSpec
from cpp_mujoco.physics.power.rotor import (
    ForwardFlightPower,
    IntervalEnergy,
    PowerModel,
    air_in_body,
)
from cpp_mujoco.physics.quadrotor import QuadrotorParams
from cpp_mujoco.physics.sensing.camera import CoverageCamera, Polygon

Reference = Callable[[float], tuple]
EMERGENCY_LANDING = "budget exhausted in flight: emergency landing where it was"


def quat_to_mat(w: float, x: float, y: float, z: float) -> tuple[float, ...]:
    """Row-major body→world rotation of a unit quaternion (MuJoCo's w, x, y, z order)."""
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz, wx, wy, wz = x * y, x * z, y * z, w * x, w * y, w * z
    return (
        1 - 2 * (yy + zz), 2 * (xy - wz), 2 * (xz + wy),
        2 * (xy + wz), 1 - 2 * (xx + zz), 2 * (yz - wx),
        2 * (xz - wy), 2 * (yz + wx), 1 - 2 * (xx + yy),
    )  # fmt: skip


def ground_contact(data, gear: frozenset, quad: frozenset, ground: int) -> bool | None:
    """None without a contact between the quadrotor (geoms ``quad``) and the ``ground`` geom;
    True if only the landing ``gear`` touches it, else False."""
    if data.ncon == 0:
        return None
    g1, g2 = data.contact.geom1[: data.ncon].tolist(), data.contact.geom2[: data.ncon].tolist()
    touching = [a if b == ground else b for a, b in zip(g1, g2, strict=True) if ground in (a, b)]
    touching = [g for g in touching if g in quad]
    if not touching:
        return None
    return all(g in gear for g in touching)


class Flight:
    """A quadrotor flying over a grid map in a compiled arena model.

    ``coverage``: the (1, H·W) bool row the camera marks (the env passes its MDP's); ``controller``
    and ``wind``: the parts (:mod:`~cpp_mujoco.physics.parts`), None for the defaults —
    ``GeometricController(params, config.controller)`` and ``Wind(config, config.control_dt)``.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        grid_map: GridMap,
        config: PhysicsConfig,
        coverage: np.ndarray | None = None,
        controller: Controller | None = None,
        wind: WindModel | None = None,
    ):
        self.model, self.config, self.map = model, config, grid_map
        self.data = mujoco.MjData(model)
        self.params = p = QuadrotorParams.from_model(model)
        self.geo = GridGeometry.of(grid_map, config.cell_size)
        self.k = config.substeps
        self.dt = config.control_dt
        self.controller = (
            controller if controller is not None else GeometricController(p, config.controller)
        )
        self.wind = wind if wind is not None else Wind(config, self.dt)
        self.drag = QuadraticDrag(config.air_density, p.drag_area)
        self.power = PowerModel(p, config.air_density)
        self.battery = Battery(PackSpec.from_config(config))  # the load's energy comes from it
        forward = (  # rotor power with the airspeed through the disks, or hover momentum theory
            ForwardFlightPower(p, config.air_density)
            if config.power_model == "forward-flight"
            else None
        )
        self.interval_energy = IntervalEnergy(
            self.power, config.timestep, p.motor_tau, self.k, forward
        )

        frame_body = int(model.body_parentid[p.body_id])
        jnt = int(model.body_jntadr[frame_body])
        if model.jnt_type[jnt] != mujoco.mjtJoint.mjJNT_FREE:
            raise ValueError("the quadrotor must hang on a free joint")
        qa, va = int(model.jnt_qposadr[jnt]), int(model.jnt_dofadr[jnt])
        d = self.data
        self._qpos, self._qvel = d.qpos[qa : qa + 7], d.qvel[va : va + 6]
        self._ctrl, self._act = d.ctrl, d.act
        self._xfrc = d.xfrc_applied[p.body_id]
        target = grid_map.target.reshape(-1)
        self.coverage = coverage if coverage is not None else np.zeros((1, target.size), bool)
        self.camera = CoverageCamera(model, d, self.geo, config, target, self.coverage)
        self.cruise_z = config.altitude - float(model.cam_pos[self.camera.cam_id][2])
        self.ground_id = int(model.geom("ground").id)
        quad_geoms = np.flatnonzero(model.body_rootid[model.geom_bodyid] == frame_body)
        gear = [model.geom(f"quadrotor/skid_{s}").id for s in "lr"]
        self.gear_geoms = frozenset(int(g) for g in gear)
        self.quad_geoms = frozenset(int(g) for g in quad_geoms)
        self.touch_z = -min(
            float(model.geom_pos[g][2]) - float(model.geom_size[g][0]) for g in self.gear_geoms
        )
        self.no_fly = grid_map.nfz.reshape(-1).tolist()
        self.cos_flip = math.cos(math.radians(config.max_tilt_deg))
        hx, hy = self.geo.half_extent
        self.bounds = (hx + config.cell_size, hy + config.cell_size, 3 * config.altitude + 5)
        self._warn_badqacc = d.warning[mujoco.mjtWarning.mjWARN_BADQACC]
        self.capacity = math.inf
        self.trace: list[tuple[float, float, float, float]] | None = None  # (t, x, y, z) per tick
        # called with the flight after every camera frame: recorders and video cameras hook here
        self.on_frame: Callable[[Flight], None] | None = None
        self.reset(0, 0)

    # ------------------------------------------------------------------ episode state
    def reset(self, row: int, col: int, capacity: float = math.inf, rng=None) -> None:
        """Hover level at cruise altitude over (row, col) with rotors at hover thrust."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        x, y = self.geo.cell_center(row, col)
        self._qpos[:3] = (x, y, self.cruise_z)
        self._qpos[3:] = (1, 0, 0, 0)
        hover = self.controller.hover_thrust()
        d.ctrl[:] = hover
        d.act[:] = hover
        mujoco.mj_forward(m, d)
        self.controller.reset()
        self.wind.reset(self.config.gust_rng(rng if rng is not None else np.random.default_rng(0)))
        self.capacity = capacity
        self.battery.reset(capacity)
        self.energy_used = 0.0
        self.motors_on = True
        self.nfz_violations = 0
        # m, the largest horizontal distance from the controller's reference this episode: the
        # margin a no-fly cell's border (half a cell from every reference) must keep
        self.max_track_error = 0.0
        self.camera.reset()
        self.coverage[:] = False
        self._bad0 = self._warn_badqacc.number

    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def position(self) -> np.ndarray:
        return self._qpos[:3].copy()

    @property
    def last_footprint(self) -> Polygon | None:
        """Ground corners of the latest camera frame (None: the horizon was in view)."""
        return self.camera.last_footprint

    def waypoint(self, cell: int) -> tuple[float, float, float]:
        row, col = divmod(int(cell), self.geo.width)
        return (*self.geo.cell_center(row, col), self.cruise_z)

    # ------------------------------------------------------------------ macro-steps
    def move(self, cell: int) -> ActionResult:
        """Fly to the centre of ``cell``; done on arrival or at the time limit."""
        c = self.config
        goal = self.waypoint(cell)
        ref = MinJerk(self.position, goal, c.move_duration, self.controller.lead)
        return self._fly(ref, goal, c.move_duration, c.move_time_limit, arrive=True)

    def hover(self, cell: int) -> ActionResult:
        """Hold over the centre of ``cell`` for one nominal move duration (a rejected action)."""
        c = self.config
        goal = self.waypoint(cell)
        ref = MinJerk(self.position, goal, c.move_duration, self.controller.lead)
        return self._fly(ref, goal, c.move_duration, c.move_duration, arrive=False)

    def land(self, cell: int) -> ActionResult:
        """Descend over ``cell`` and touch down; touchdown is a landing-gear/ground contact."""
        c = self.config
        x, y, _ = self.waypoint(cell)
        ref = self._descent(self.position, x, y)
        return self._fly(ref, (x, y, self.touch_z), c.land_duration, c.land_time_limit, land=True)

    def _descent(self, start, x: float, y: float) -> Reference:
        """Minimum-jerk descent from ``start`` to a flare just above the ground at (x, y), then
        a constant sink until the landing gear touches."""
        c = self.config
        flare = self.touch_z + 0.3
        descent = MinJerk(start, (x, y, flare), c.land_duration, self.controller.lead)
        speed = c.land_speed

        def ref(t: float):
            if t < c.land_duration:
                return descent(t)
            return (x, y, flare - speed * (t - c.land_duration)), (0.0, 0.0, -speed), (0, 0, 0)

        return ref

    def _emergency_descent(self, pos) -> Reference:
        """The battery failsafe of a real autopilot (PX4 ``COM_LOW_BAT_ACT`` "Land", ArduPilot
        ``BATT_FS_CRT_ACT`` "Land"): land straight down where the UAV is, on the pack's reserve,
        rather than cutting the motors and falling across whatever airspace lies downwind."""
        return self._descent(pos, pos[0], pos[1])

    # ------------------------------------------------------------------ the loop
    def _fly(self, ref: Reference, goal, nominal, limit, arrive=False, land=False) -> ActionResult:
        out = ActionResult()
        e0, t0 = self.energy_used, self.time
        out.newly_seen += self.frame()
        m, d, k, dt = self.model, self.data, self.k, self.dt
        qpos, qvel, ctrl, act, xfrc = self._qpos, self._qvel, self._ctrl, self._act, self._xfrc
        controller, energy_of, battery = self.controller, self.interval_energy, self.battery
        airspeed_power = getattr(energy_of, "forward", None) is not None
        wind, drag = self.wind.velocity, self.drag.force
        cell_index, no_fly, camera = self.geo.cell_index, self.no_fly, self.camera
        bx, by, bz = self.bounds
        pos_tol2, vel_tol2 = self.config.arrive_pos_tol**2, self.config.arrive_vel_tol**2
        max_err2 = self.config.max_tracking_error**2
        zero = [0.0, 0.0, 0.0, 0.0]
        trace, warn, bad0, cos_flip = self.trace, self._warn_badqacc, self._bad0, self.cos_flip
        step, t = mujoco.mj_step, 0.0
        worst2 = self.max_track_error**2
        emergency: str | None = None  # why the battery failsafe is landing the UAV
        # a landing begun with budget left finishes on the reserve: the failsafe would land
        # right there anyway, and on the grid a landing with one unit left always succeeds
        landing = land
        while True:
            qp = qpos.tolist()
            qv = qvel.tolist()
            pos, vel = qp[:3], qv[:3]
            if trace is not None:
                trace.append((d.time, *pos))
            R = quat_to_mat(*qp[3:])
            # ---- failure checks on the current state
            failure = None
            if not math.isfinite(sum(qp)) or warn.number != bad0:
                failure = "numerical divergence (NaN or unstable acceleration)"
            elif abs(pos[0]) > bx or abs(pos[1]) > by or pos[2] > bz:
                failure = "left the arena"
            elif R[8] < cos_flip and self.motors_on:
                failure = "flipped over"
            # no-fly airspace: the body's xy inside a no-fly cell (outside the grid counts)
            cell = cell_index(pos[0], pos[1])
            if cell is None or no_fly[cell]:
                self.nfz_violations += k
            p_ref, v_ref, a_ref = ref(t)
            if failure is None and self.motors_on:
                ex, ey, ez = pos[0] - p_ref[0], pos[1] - p_ref[1], pos[2] - p_ref[2]
                off2 = ex * ex + ey * ey
                if off2 > worst2:
                    worst2 = off2
                if off2 + ez * ez > max_err2:
                    failure = "diverged from the reference"
            if failure is not None:
                out.failure = failure
                break
            if t0 + t >= camera.next_frame:
                out.newly_seen += self.frame()
            # ---- done?
            if not self.motors_on:
                if self._ground_contact() is not None or t >= self.config.fall_time_limit:
                    out.failure = battery.failure
                    break
            elif land:
                touch = self._ground_contact()
                if touch is not None:
                    if not touch:
                        out.failure = "hit the ground with the airframe, not the landing gear"
                    elif emergency is not None:
                        out.failure = emergency
                        self._settle()
                    else:
                        out.landed = out.arrived = True
                        self._settle()
                    break
                if t >= limit:
                    out.failure = "no touchdown within the landing time limit"
                    break
            elif t >= nominal:
                gx, gy, gz = pos[0] - goal[0], pos[1] - goal[1], pos[2] - goal[2]
                near = gx * gx + gy * gy + gz * gz < pos_tol2
                slow = vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2] < vel_tol2
                if arrive and near and slow:
                    out.arrived = True
                    break
                if t >= limit - 1e-9:
                    break
            # ---- control, energy, wind, physics
            w = wind(d.time, pos)  # once per tick: stateful wind models advance on each call
            if self.motors_on:
                thrusts = act.tolist()
                controller.observe(vel, R, thrusts, dt)
                f = controller(pos, vel, R, qv[3:], p_ref, v_ref, a_ref, dt)
                e = energy_of(thrusts, f, air_in_body(vel, w, R) if airspeed_power else None)
                e = battery.draw(e / dt, dt)  # J from the pack: the load plus its I²R loss
                if e is None:  # the pack cannot carry the load: the motors stop
                    self.motors_on = False
                    battery.idle()
                    f, t = zero, 0.0  # the fall gets its own time limit
                else:
                    self.energy_used += e
                    if (
                        not landing
                        and emergency is None
                        and (battery.below_cutoff or self.energy_used >= self.capacity)
                    ):  # the battery failsafe: land where it is, on the reserve
                        emergency = CUTOFF if battery.below_cutoff else EMERGENCY_LANDING
                        land, t, limit = True, 0.0, self.config.land_time_limit
                        ref = self._emergency_descent(pos)
                        goal = (pos[0], pos[1], self.touch_z)
            else:
                f = zero
            ctrl[:] = f
            xfrc[:3] = drag(vel, w)
            step(m, d, k)
            t += dt
        self.max_track_error = math.sqrt(worst2)
        out.newly_seen += self.frame()
        out.duration = self.time - t0
        out.energy = self.energy_used - e0
        p = self._qpos[:3]
        out.tracking_error = float(math.dist(p.tolist(), goal))
        return out

    def _ground_contact(self) -> bool | None:
        return ground_contact(self.data, self.gear_geoms, self.quad_geoms, self.ground_id)

    def _settle(self, seconds: float = 0.3) -> None:
        """Motors off after touchdown; let the airframe come to rest on its skids."""
        self._ctrl[:] = 0.0
        self.motors_on = False
        self.battery.idle()
        self._xfrc[:3] = 0.0
        mujoco.mj_step(self.model, self.data, nstep=max(1, round(seconds / self.config.timestep)))

    # ------------------------------------------------------------------ camera
    def frame(self) -> int:
        """Take a coverage frame now (:meth:`CoverageCamera.capture`), then call :attr:`on_frame`;
        return how many target cells it saw first."""
        newly = self.camera.capture(float(self.data.time))
        if self.on_frame is not None:
            self.on_frame(self)
        return newly
