"""Cheaper physics steps in the air: drones that cannot touch the ground step without contacts.

Why: at cruise altitude a drone has nothing to collide with, yet every ``mj_step`` runs MuJoCo's
collision and constraint stages. A second copy of the model with both disabled
(``mjDSBL_CONTACT | mjDSBL_CONSTRAINT``) skips them; the batch steps each drone on the model its
height allows (``Batch.set_models``). In the air the full model finds no contact and builds no
constraint, so both compute the same doubles, warmstart included: the flight is bit-identical
(``tests/test_airborne_steps.py``), only cheaper (``python -m cpp_mujoco.bench.physics 4
--batched 128``: ``air_steps_speedup``, ``raw_air_mj_step_per_s``).

A drone counts as airborne for the next call of ``nstep`` substeps when even its lowest reach
(the farthest point of its collidable geoms from its origin, margins included) stays above the
highest collidable world geom after falling at its current sink rate plus a 4 g acceleration and
a fixed clearance: so no contact can begin during the call. A state no flight reaches (NaN, a
speed past 50 m/s or 50 rad/s, kilometres away) steps on the full model, which is the one whose
numerics such a state tests, so even a diverging drone fails at the same tick as on its own.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np
from numba import njit

CLEARANCE = 0.1  # m, kept between the drone's lowest reach and the ground on top of the fall
MAX_DOWN_ACCELERATION = 4 * 9.81  # m/s², above any the airframe can reach (thrust ≤ 2.2 g)
MAX_RATE = 50.0  # m/s and rad/s: faster than any flight (the cruise is 2–5 m/s)
MAX_DISTANCE = 1e3  # m from the origin


def air_model(model: mujoco.MjModel) -> mujoco.MjModel:
    """``model`` without the collision and constraint stages (same sizes, same MjData layout)."""
    air = copy.copy(model)
    air.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | int(
        mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    )
    return air


def _collides(model: mujoco.MjModel) -> np.ndarray:
    return (model.geom_contype != 0) | (model.geom_conaffinity != 0)


def reach_below(model: mujoco.MjModel, body: int, every_geom: bool = False) -> float:
    """How far from the origin of ``body`` (a free body) its collidable geoms (``every_geom``:
    all its geoms, the airframe's bounding sphere) and those of its descendants can reach, in
    any attitude: the bodies' offsets add along the chain."""
    far = 0.0
    geoms = np.ones(model.ngeom, dtype=bool) if every_geom else _collides(model)
    for g in np.flatnonzero(geoms).tolist():
        b, offset = int(model.geom_bodyid[g]), 0.0
        while b not in (body, 0):
            offset += float(np.linalg.norm(model.body_pos[b]))
            b = int(model.body_parentid[b])
        if b == body:
            size = np.linalg.norm(model.geom_pos[g]) + model.geom_rbound[g] + model.geom_margin[g]
            far = max(far, offset + float(size))
    return far


def ground_top(model: mujoco.MjModel) -> float:
    """The height of the highest collidable world geom (a plane: its height; else its top)."""
    world = _collides(model) & (model.geom_bodyid == 0)
    plane = model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE
    top = model.geom_pos[:, 2] + np.where(plane, 0.0, model.geom_rbound) + model.geom_margin
    return float(np.max(top[world])) if np.any(world) else -np.inf


class AirborneSteps:
    """Picks, per drone and call, the model ``sims`` steps it on: the air model while it is
    clear of the ground, the batch's own otherwise. ``pos``, ``vel``: (n, 3) and (n, 6) views of
    the free body's position and velocity (linear, angular) in the batch's state rows."""

    def __init__(self, sims, model: mujoco.MjModel, body: int, pos: np.ndarray, vel: np.ndarray):
        self.sims, self.pos, self.vel = sims, pos, vel
        self.models = (model, air_model(model))
        self.floor = ground_top(model) + reach_below(model, body) + CLEARANCE
        self.dt = model.opt.timestep
        self.airborne = np.zeros(len(pos), dtype=bool)  # the models the batch holds now
        self._clear = np.zeros(len(pos), dtype=bool)

    def clear(self, drones: np.ndarray, nstep: int) -> np.ndarray:
        """Whether each of ``drones`` stays clear of the ground for ``nstep`` substeps."""
        out = self._clear[: len(drones)]
        clear_of_ground(drones, self.pos, self.vel, self.floor, nstep * self.dt, out)
        return out

    def before_step(self, drones: np.ndarray, nstep: int) -> None:
        """Set the models of ``drones`` for their next ``nstep`` substeps (one C call to the
        batch, and only when some drone changes side)."""
        if not changed(drones, self.clear(drones, nstep), self.airborne):
            return
        ground, air = self.models
        self.sims.set_models([air if a else ground for a in self.airborne.tolist()])


@njit(cache=True)
def clear_of_ground(drones, pos, vel, floor, t, out):
    """:meth:`AirborneSteps.clear` into ``out``: sane, and above the floor after a fall of
    ``t`` seconds at the sink rate plus the largest downward acceleration."""
    for j in range(drones.size):
        d = drones[j]
        sane = True
        for k in range(6):
            if not abs(vel[d, k]) < MAX_RATE:
                sane = False
        for k in range(3):
            if not abs(pos[d, k]) < MAX_DISTANCE:
                sane = False
        sink = max(-vel[d, 2], 0.0)
        low = floor + sink * t + 0.5 * MAX_DOWN_ACCELERATION * t * t
        out[j] = sane and pos[d, 2] > low


@njit(cache=True)
def changed(drones, clear, airborne) -> bool:
    """Write ``clear`` into ``airborne[drones]``; whether any entry changed."""
    moved = False
    for j in range(drones.size):
        if airborne[drones[j]] != clear[j]:
            airborne[drones[j]] = clear[j]
            moved = True
    return moved
