"""The flight: N quadrotors flying grid actions as macro-actions of control ticks and MuJoCo
steps — the one flight of the physics backend (``MuJoCo-v0`` is a batch of one of it).

Parts: the vehicle is the compiled model (:mod:`~cpp_mujoco.physics.arena`); the controller
(:mod:`~cpp_mujoco.physics.control`) and the wind (:mod:`~cpp_mujoco.physics.air`) are
swappable (:mod:`~cpp_mujoco.physics.parts`); the rotor power and the pack
(:mod:`~cpp_mujoco.physics.power`), the coverage camera (:mod:`~cpp_mujoco.physics.sensing`) and
the obstacle check (:mod:`~cpp_mujoco.physics.obstacles`) are the flight's own.

Rates: MuJoCo steps every ``timestep``; the controller, wind, drag, energy and failure checks run
every ``substeps`` physics steps; the camera takes a frame at ``camera_rate`` plus one at the
start and end of every action. Energy is the sum over physics steps of the thrust's power,
scaled per tick by the forward-flight factor of the tick's airspeed; no-fly violations are
sampled per tick and counted as ``substeps`` physics steps each.

How: a tick's work is done once for all drones, in three compiled kernels
(:mod:`~cpp_mujoco.physics.tick`), and the physics of all drones is one call of
``mujoco.batch.Batch.step`` (MuJoCo ≥ 3.17): C loops over the drones on ``threads`` threads
without the GIL. The batch is *persistent*: each drone keeps its own ``MjData`` inside it, and its
state row (:attr:`Flight.state`, ``mjSTATE_INTEGRATION``) carries the solver's warmstart and the
inputs — every step is an ``mj_step``: contacts (touchdown) and the camera pose (coverage) are
MuJoCo's own. Drones clear of the ground step on a model without contacts
(:mod:`~cpp_mujoco.physics.airborne`), the same doubles.

A macro-action ends at a different time for each drone; the drones that are done wait (no
physics) while the others fly, so a drone's flight does not depend on the batch it flies in.
What stays per drone in plain Python is what happens once per action or near the ground: the
failure messages, the touchdown checks while landing (a drone's ``MjData`` is copied out of the
batch only at a tick with contacts) and the motors-off settle.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np
from mujoco.batch import Batch

from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.action import HOVER, LAND, MOVE, ActionResult, MacroActions
from cpp_mujoco.physics.air.wind import Wind
from cpp_mujoco.physics.airborne import AirborneSteps, reach_below
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.control.controller import GeometricController, References
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.physics.obstacles import ObstacleCrashes, obstacle_boxes
from cpp_mujoco.physics.parts import Controller, WindModel
from cpp_mujoco.physics.power.battery import CUTOFF, Battery, PackSpec
from cpp_mujoco.physics.power.rotor import ForwardFlightPower, IntervalEnergy, PowerModel
from cpp_mujoco.physics.quadrotor import QuadrotorParams
from cpp_mujoco.physics.sensing.camera import CoverageCamera, Polygon
from cpp_mujoco.physics.tick import Tick

EMERGENCY_LANDING = "budget exhausted in flight: emergency landing where it was"
_ROW = int(mujoco.mjtState.mjSTATE_INTEGRATION)  # the batch's state rows


def _column(model: mujoco.MjModel, component: mujoco.mjtState) -> int:
    """First column of a state component in a row: components are stored in bit order."""
    return mujoco.mj_stateSize(model, (int(component) - 1) & _ROW)


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
    """``n`` drones over one map and model. ``coverage``: the (n, H·W) bool rows the cameras
    mark (the env passes its MDP's); ``threads``: how many threads step the physics (the
    caller's included); ``air_steps``: drones clear of the ground step without contacts (the
    same doubles, cheaper); ``controller`` and ``wind``: a user's parts
    (:mod:`~cpp_mujoco.physics.parts`), None for the built-in ones (:attr:`law`: the geometric
    controller with ``config.controller`` gains, :attr:`weather`: ``config``'s wind). The batch
    steps a copy of ``model``, made here."""

    def __init__(
        self,
        model: mujoco.MjModel,
        grid_map: GridMap,
        config: PhysicsConfig,
        n: int,
        coverage: np.ndarray,
        threads: int = 1,
        air_steps: bool = True,
        controller: Controller | None = None,
        wind: WindModel | None = None,
    ):
        self.model, self.config, self.n = model, config, n
        self.k, self.dt = config.substeps, config.control_dt
        self.params = p = QuadrotorParams.from_model(model)
        self.geo = GridGeometry.of(grid_map, config.cell_size)
        self.law = GeometricController(p, config.controller, n)
        self.weather = Wind(config, self.dt, n)
        self.controller = controller if controller is not None else self.law
        self.wind = wind if wind is not None else self.weather
        self.half_rho_cda = 0.5 * config.air_density * p.drag_area  # the airframe's drag
        forward = (  # rotor power with the airspeed through the disks, or hover momentum theory
            ForwardFlightPower(p, config.air_density)
            if config.power_model == "forward-flight"
            else None
        )
        power = PowerModel(p, config.air_density)
        self.energy_of = IntervalEnergy(power, config.timestep, p.motor_tau, self.k, forward)
        self.battery = Battery(PackSpec.from_config(config), n)
        self.wind_now = np.zeros((n, 3))  # m/s, the wind each drone's last tick flew in
        # called with a drone's index after each of its camera frames (videos, recordings)
        self.on_frame: Callable[[int], None] | None = None
        self.trace: list | None = None  # drone 0's (t, x, y, z) at every tick, when a list
        self.threads = max(1, int(threads))
        # one persistent MjData per drone, stepped in C (the batch copies the model once)
        self.sims = sims = Batch(model, n, nthread=self.threads, persistent=True)
        # (n, nstate) live rows: time, qpos, qvel, act, warmstart, ctrl, …, xfrc_applied
        self.state = sims.state
        self._ncon = sims.bind("ncon")  # each drone's contacts of its last step
        # MuJoCo's count of its divergence resets (a bad acceleration), per drone, against
        # the count at the episode's start
        self._bad = sims.warning[:, mujoco.mjtWarning.mjWARN_BADQACC, 1]
        self._bad0 = np.zeros(n, dtype=self._bad.dtype)
        self._contacts = mujoco.MjData(model)  # a drone's MjData copied out, to read them
        boxes = obstacle_boxes(grid_map, config) if grid_map.has_obstacles else None
        self.camera = CoverageCamera(
            model, sims.bind("cam_xpos"), sims.bind("cam_xmat"), self.state[:, 0], self.geo,
            config, grid_map.target, coverage, obstacles=boxes, body=p.body_id,
        )  # fmt: skip
        self.coverage = coverage
        self.refs = References(n, self.controller.lead, config.land_duration, config.land_speed)
        self._geometry(model, grid_map)
        self.capacity = np.full(n, math.inf)
        self.energy_used = np.zeros(n)
        self.motors_on = np.ones(n, dtype=bool)
        self.nfz_violations = np.zeros(n, dtype=np.int64)
        self.max_track_error = np.zeros(n)
        self.no_fly = np.asarray(grid_map.nfz, dtype=bool).reshape(-1)
        # obstacles crash a drone on either model, the contact-free one included (obstacles.py)
        self.obstacles = None if boxes is None else ObstacleCrashes(
            boxes, reach_below(model, self._frame, every_geom=True), n
        )  # fmt: skip
        self.air = AirborneSteps(sims, model, self._frame, *self._live) if air_steps else None
        self._tick = Tick(self)

    def _geometry(self, model: mujoco.MjModel, grid_map: GridMap) -> None:
        """Where the drone's state sits in a row, and the heights, geoms and bounds the flight
        checks against."""
        config, S = self.config, mujoco.mjtState
        frame = int(model.body_parentid[self.params.body_id])  # the body of the free joint
        jnt = int(model.body_jntadr[frame])
        if model.jnt_type[jnt] != mujoco.mjtJoint.mjJNT_FREE:
            raise ValueError("the quadrotor must hang on a free joint")
        q0 = _column(model, S.mjSTATE_QPOS) + int(model.jnt_qposadr[jnt])
        v0 = _column(model, S.mjSTATE_QVEL) + int(model.jnt_dofadr[jnt])
        a0 = _column(model, S.mjSTATE_ACT)
        self.cols = (slice(q0, q0 + 7), slice(v0, v0 + 6), slice(a0, a0 + model.na))
        u0 = _column(model, S.mjSTATE_CTRL)
        self.ctrl_cols = slice(u0, u0 + model.nu)
        f0 = _column(model, S.mjSTATE_XFRC_APPLIED) + 6 * self.params.body_id
        self.force_cols = slice(f0, f0 + 3)  # the drag force on the body
        self._frame, self._live = frame, (self.state[:, q0 : q0 + 3], self.state[:, v0 : v0 + 6])
        self.cruise_z = config.altitude - float(model.cam_pos[self.camera.cam_id][2])
        self.ground_id = int(model.geom("ground").id)
        quad_geoms = np.flatnonzero(model.body_rootid[model.geom_bodyid] == frame)
        gear = [model.geom(f"quadrotor/skid_{s}").id for s in "lr"]
        self.gear_geoms = frozenset(int(g) for g in gear)
        self.quad_geoms = frozenset(int(g) for g in quad_geoms)
        self.touch_z = -min(
            float(model.geom_pos[g][2]) - float(model.geom_size[g][0]) for g in self.gear_geoms
        )
        self.cos_flip = math.cos(math.radians(config.max_tilt_deg))
        hx, hy = self.geo.half_extent
        self.bounds = (hx + config.cell_size, hy + config.cell_size, 3 * config.altitude + 5)

    @classmethod
    def alone(cls, grid_map: GridMap, config: PhysicsConfig) -> Flight:
        """One drone over ``grid_map`` in an arena of its own (calibration, energy tables)."""
        model = compile_arena(build_arena(grid_map, config))
        return cls(model, grid_map, config, 1, np.zeros((1, grid_map.target.size), dtype=bool))

    def close(self) -> None:
        """Nothing to release: the batch's threads idle without CPU and go with the object."""

    # ------------------------------------------------------------------ episode state
    def reset(self, i: int, row: int, col: int, capacity: float, rng: np.random.Generator):
        """Drone ``i`` hovers level at cruise altitude over (row, col), rotors at hover thrust
        (``mj_resetData``, the pose and thrusts written, ``mj_forward``); its pack holds
        ``capacity`` J, its wind draws from ``rng`` (through ``config.gust_rng``)."""
        st = self.state
        self.sims.reset([i], stage=mujoco.mjtStage.mjSTAGE_NONE)
        x, y = self.geo.cell_center(row, col)
        q = self.cols[0].start
        st[i, q : q + 7] = (x, y, self.cruise_z, 1, 0, 0, 0)
        hover = self.controller.hover_thrust()
        st[i, self.ctrl_cols] = hover
        st[i, self.cols[2]] = hover
        self.sims.forward([i])
        self.controller.reset(i)
        self.wind.reset(i, self.config.gust_rng(rng))
        self.capacity[i] = capacity
        self.battery.reset(i, capacity)
        self.energy_used[i] = 0.0
        self.motors_on[i] = True
        self.nfz_violations[i] = 0
        self.max_track_error[i] = 0.0
        self.camera.reset(i)
        self.wind_now[i] = np.nan  # no tick flown yet
        self.coverage[i] = False
        self._bad0[i] = self._bad[i]

    def set_wind_direction(self, i: int, direction: float) -> None:
        """Drone ``i``'s steady wind blows from ``direction`` (degrees, as ``wind_direction``)
        from its next episode on: the wind of that configuration, so its flight is a
        single env's with ``wind_direction=direction``."""
        self.weather.set_direction(i, direction)

    def position(self, i: int) -> np.ndarray:
        return self.state[i, self.cols[0]][:3].copy()

    def waypoint(self, cell: int) -> tuple[float, float, float]:
        """The point a move to ``cell`` flies to: its centre at cruise altitude."""
        row, col = divmod(int(cell), self.geo.width)
        return (*self.geo.cell_center(row, col), self.cruise_z)

    def copy_data(self, i: int, data: mujoco.MjData) -> mujoco.MjData:
        """Drone ``i``'s whole ``MjData`` copied into ``data`` (to render or inspect it)."""
        return self.sims.get_data(i, data)

    def footprint(self, i: int) -> Polygon | None:
        """Ground corners of drone ``i``'s camera image now (None: the horizon is in view)."""
        return self.camera.footprint(i)

    def capture(self, drones: np.ndarray) -> np.ndarray:
        """A camera frame of each of ``drones`` now (:meth:`CoverageCamera.capture`), then
        :attr:`on_frame` for each; how many target cells each saw first."""
        newly = self.camera.capture(drones)
        if self.on_frame is not None:
            for d in np.asarray(drones).tolist():
                self.on_frame(int(d))
        return newly

    # ------------------------------------------------------------------ physics
    def _step(self, drones: np.ndarray, nstep: int) -> None:
        """``nstep`` physics steps of ``drones`` (sorted) with the ctrl and body force in
        their rows: one ``Batch.step``, split over the threads in C. A diverging drone (a NaN
        or huge acceleration) is reset by MuJoCo, which counts it in the drone's warnings: the
        next tick's failure check reads that count, as the single flight does."""
        if self.air is not None:
            self.air.before_step(drones, nstep)
        self.sims.step(None if drones.size == self.n else drones, nstep)  # None: all, no checks

    def _ground_contact(self, i: int) -> bool | None:
        """:func:`ground_contact` of drone ``i``'s last step; its ``MjData`` is copied out of the
        batch only when it had contacts (touchdown: a few ticks per landing)."""
        if self._ncon[i] == 0:
            return None
        data = self.sims.get_data(i, self._contacts)
        return ground_contact(data, self.gear_geoms, self.quad_geoms, self.ground_id)

    def _settle(self, i: int, seconds: float = 0.3) -> None:
        """Motors off after touchdown: the airframe comes to rest on its skids."""
        self.motors_on[i] = False
        self.battery.current[i] = 0.0
        self.state[i, self.ctrl_cols] = 0.0
        self.state[i, self.force_cols] = 0.0
        self._step(np.array([i]), max(1, round(seconds / self.config.timestep)))

    # ------------------------------------------------------------------ macro-steps
    def fly(self, kinds: np.ndarray, cells: np.ndarray, active: np.ndarray) -> dict:
        """Fly one macro-action per ``active`` drone (``kinds``: MOVE to / HOVER over / LAND on
        ``cells``); the result fields of :class:`~cpp_mujoco.physics.action.ActionResult` as
        (n,) arrays (zero for drones not active)."""
        n, c = self.n, self.config
        res = {
            "duration": np.zeros(n), "energy": np.zeros(n),
            "newly_seen": np.zeros(n, dtype=np.int64), "arrived": np.zeros(n, dtype=bool),
            "landed": np.zeros(n, dtype=bool), "tracking_error": np.zeros(n),
            "failure": np.full(n, None, dtype=object),
        }  # fmt: skip
        idx = np.flatnonzero(active)
        if idx.size == 0:
            return res
        e0, t0 = self.energy_used.copy(), self.state[:, 0].copy()
        res["newly_seen"][idx] += self.capture(idx)
        kind = kinds[idx]
        rows, cols = np.divmod(cells[idx], self.geo.width)
        x, y = self.geo.cell_center(rows, cols)
        landing = kind == LAND
        z = np.where(landing, self.touch_z + 0.3, self.cruise_z)
        pos = self.state[idx, self.cols[0]][:, :3]
        self.refs.set(
            idx, pos, np.stack([x, y, z], 1), np.where(landing, c.land_duration, c.move_duration),
            landing,
        )  # fmt: skip
        goal = np.zeros((n, 3))
        goal[idx] = np.stack([x, y, np.where(landing, self.touch_z, self.cruise_z)], 1)
        nominal = np.zeros(n)
        nominal[idx] = np.where(landing, c.land_duration, c.move_duration)
        limit = np.zeros(n)
        limit[idx] = np.select(
            [kind == MOVE, kind == HOVER], [c.move_time_limit, c.move_duration], c.land_time_limit
        )
        arrive = np.zeros(n, dtype=bool)
        arrive[idx] = kind == MOVE
        land = np.zeros(n, dtype=bool)
        land[idx] = landing
        action = MacroActions(
            res, active.copy(), np.zeros(n), t0, goal, nominal, limit, arrive, land,
            land.copy(), np.full(n, None, dtype=object), self.max_track_error**2,
        )  # fmt: skip
        self._loop(action)
        self.max_track_error[idx] = np.sqrt(action.worst2[idx])
        res["newly_seen"][idx] += self.capture(idx)
        res["duration"][idx] = self.state[idx, 0] - t0[idx]
        res["energy"][idx] = self.energy_used[idx] - e0[idx]
        p = self.state[idx, self.cols[0]][:, :3]
        res["tracking_error"][idx] = np.sqrt(((p - goal[idx]) ** 2).sum(1))
        return res

    def fly_one(self, kind: int, cell: int, i: int = 0) -> ActionResult:
        """One macro-action of drone ``i`` alone (the others wait): MOVE to, HOVER over or
        LAND on ``cell``."""
        active = np.zeros(self.n, dtype=bool)
        active[i] = True
        res = self.fly(np.full(self.n, kind), np.full(self.n, cell), active)
        return ActionResult(**{k: v[i].item() if k != "failure" else v[i] for k, v in res.items()})

    def _loop(self, a: MacroActions) -> None:
        """The tick loop over the drones still flying: one control tick
        for all of them (:meth:`_tick`), then their physics steps (one C call)."""
        k, dt, tick, q = self.k, self.dt, self._tick, self.cols[0].start
        i = np.flatnonzero(a.flying)
        while i.size:
            if self.trace is not None and a.flying[0]:
                self.trace.append(tuple(self.state[0, [0, q, q + 1, q + 2]].tolist()))
            go = tick(i, a)
            if go.size:
                self._step(go, k)
                a.t[go] += dt
            i = np.flatnonzero(a.flying)

    def _landing_done(self, d: int, a: MacroActions) -> bool:
        """Whether landing or falling drone ``d``'s action ends (contact, time limit)."""
        res, t = a.res, a.t[d]
        touch = self._ground_contact(d)
        if not self.motors_on[d]:
            if touch is None and t < self.config.fall_time_limit:
                return False
            res["failure"][d] = self.battery.failure[d]
        elif touch is not None:
            if not touch:
                res["failure"][d] = "hit the ground with the airframe, not the landing gear"
            elif a.emergency[d] is not None:
                res["failure"][d] = a.emergency[d]
                self._settle(d)
            else:
                res["landed"][d] = res["arrived"][d] = True
                self._settle(d)
        elif t >= a.limit[d]:
            res["failure"][d] = "no touchdown within the landing time limit"
        else:
            return False
        return True

    def _failsafe(self, d: np.ndarray, p: np.ndarray, a: MacroActions) -> None:
        """The battery failsafe: drones ``d`` at ``p`` (m, 3) land where they are, on the
        reserve (the cut-off's or the budget's)."""
        c = self.config
        a.emergency[d] = np.where(self.battery.below_cutoff[d], CUTOFF, EMERGENCY_LANDING)
        a.land[d], a.t[d], a.limit[d] = True, 0.0, c.land_time_limit
        end = np.stack([p[:, 0], p[:, 1], np.full(len(d), self.touch_z + 0.3)], 1)
        self.refs.set(d, p, end, np.full(len(d), c.land_duration), True)
        a.goal[d] = np.stack([p[:, 0], p[:, 1], np.full(len(d), self.touch_z)], 1)
