"""The quadrotor as a reviewer sees it: an enlarged airframe drawn at render time.

Why not the model's own geoms: the real 450-size frame is a dozen pixels across in a chase frame
that shows 3×3 cells of 4 m, and every geom added to the physics model costs every ``mj_step``.
So the model stays as it is (the chase camera hides its visual group) and :class:`Airframe`
appends an airframe ``scale`` times larger to the scene, placed from the body's pose
(``data.xpos`` / ``data.xmat`` of ``quadrotor/core``): hub, battery, arms (front ones red), motors,
rotor discs and landing skids. It is scaled about the skids' lowest point, so a landed UAV still
stands on the ground. Rotor discs brighten with each rotor's thrust (``data.act``), which shows
a climb, a hover and the motors stopping after a landing.
"""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["AIRFRAME_SCALE", "Airframe"]

AIRFRAME_SCALE = 3.0  # ~40 px across in a 512×384 chase frame at 14 m
BODY = "quadrotor/core"
ARM = 0.159  # m, rotor axis offset along x and y (assets/quadrotor.xml)
ROTOR_RADIUS = 0.127  # m
ROTOR_Z = 0.035  # m above the body origin
SKID_Z = -0.178  # m, the skids' lowest point: the scale's fixed point
_ROTORS = ((1, 1), (1, -1), (-1, -1), (-1, 1))  # fl, fr, rr, rl as (x, y) signs
ROTOR_NAMES = ("fl", "fr", "rr", "rl")
_ROTOR_IDLE = np.array([0.30, 0.30, 0.35, 0.45], dtype=np.float32)  # motors off: dim, see-through
_ROTOR_FULL = np.array([0.60, 0.95, 1.00, 0.55], dtype=np.float32)
_DARK, _HUB, _BATTERY = (0.12, 0.12, 0.14, 1.0), (0.92, 0.92, 0.95, 1.0), (0.2, 0.3, 0.75, 1.0)
_FRONT, _REAR = (0.9, 0.15, 0.12, 1.0), (0.95, 0.95, 0.95, 1.0)


def _segment(a, b) -> tuple[np.ndarray, np.ndarray, float]:
    """Centre, rotation (z along a→b) and half length of a capsule from ``a`` to ``b``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = b - a
    length = float(np.linalg.norm(axis))
    z = axis / length
    x = np.cross([0.0, 0.0, 1.0], z) if abs(z[2]) < 0.9 else np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    return (a + b) / 2, np.column_stack([x, np.cross(z, x), z]), length / 2


class Airframe:
    """The enlarged airframe of the model's quadrotor; :meth:`decorate` appends it to a scene.

    Sizes follow MJCF (``mjv_initGeom`` reads them so): a box's half sides; a capsule's or a
    cylinder's radius and half length. Parts are kept in the body frame (already scaled); a
    frame only rotates them by ``data.xmat`` and moves them to ``data.xpos`` (one batched numpy
    product), then copies them.
    """

    def __init__(self, model: mujoco.MjModel, scale: float = AIRFRAME_SCALE, body: str = BODY):
        self.body_id = int(model.body(body).id)
        self.scale = scale
        try:  # the four thrusters, in _ROTORS' order
            acts = [int(model.actuator(f"quadrotor/thrust_{n}").id) for n in ROTOR_NAMES]
        except KeyError:  # another vehicle: discs drawn idle
            acts = []
        ids = np.array(acts, dtype=int)
        self._act_ids = model.actuator_actadr[ids] if acts else ids  # their thrust in data.act
        top = model.actuator_ctrlrange[ids, 1] if acts else np.ones(0)
        self._act_max = np.where(top > 0, top, 1.0)
        cap, box, cyl = (int(t) for t in (mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_BOX,
                                          mujoco.mjtGeom.mjGEOM_CYLINDER))  # fmt: skip
        eye = np.eye(3)
        parts: list[tuple[int, np.ndarray, np.ndarray, np.ndarray, tuple]] = [
            (box, np.zeros(3), eye, np.array([0.075, 0.075, 0.03]), _HUB),
            (box, np.array([0, 0, -0.045]), eye, np.array([0.07, 0.025, 0.018]), _BATTERY),
        ]
        for sx, sy in _ROTORS:
            centre, rot, half = _segment((0, 0, 0), (sx * ARM, sy * ARM, 0))
            parts.append((cap, centre, rot, np.array([0.016, half, 0]),
                          _FRONT if sx > 0 else _REAR))  # fmt: skip
        for sx, sy in _ROTORS:
            parts.append((cyl, np.array([sx * ARM, sy * ARM, 0.012]), eye,
                          np.array([0.022, 0.02, 0]), _DARK))  # fmt: skip
        for side in (1, -1):
            centre, rot, half = _segment((0, side * 0.07, -0.02), (0, side * 0.11, SKID_Z + 0.008))
            parts.append((cap, centre, rot, np.array([0.009, half, 0]), _DARK))
            centre, rot, half = _segment((-0.11, side * 0.11, SKID_Z + 0.008),
                                         (0.11, side * 0.11, SKID_Z + 0.008))  # fmt: skip
            parts.append((cap, centre, rot, np.array([0.009, half, 0]), _DARK))
        self._first_disc = len(parts)
        for sx, sy in _ROTORS:
            parts.append((cyl, np.array([sx * ARM, sy * ARM, ROTOR_Z]), eye,
                          np.array([ROTOR_RADIUS, 0.004, 0]), tuple(_ROTOR_IDLE)))  # fmt: skip
        anchor = np.array([0.0, 0.0, SKID_Z])
        self._types = [p[0] for p in parts]
        self._pos = np.array([anchor + scale * (p[1] - anchor) for p in parts])  # body frame
        self._rot = np.array([p[2] for p in parts])
        self._size = [np.asarray(p[3]) * scale for p in parts]
        self._rgba = np.array([p[4] for p in parts], dtype=np.float32)

    @property
    def geom_count(self) -> int:
        return len(self._types)

    def thrust_fraction(self, data: mujoco.MjData) -> np.ndarray:
        """Each rotor's thrust as a fraction of its maximum (0 with the motors off)."""
        if not len(self._act_ids):
            return np.zeros(4)
        return np.clip(np.asarray(data.act)[self._act_ids] / self._act_max, 0.0, 1.0)

    def pose(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """World centres (N, 3) and rotations (N, 3, 3) of the parts in this state."""
        xpos = np.asarray(data.xpos[self.body_id])
        xmat = np.asarray(data.xmat[self.body_id]).reshape(3, 3)
        return xpos + self._pos @ xmat.T, np.einsum("ij,njk->nik", xmat, self._rot)

    def decorate(self, scene: mujoco.MjvScene, data: mujoco.MjData) -> None:
        """Append the airframe at the body's pose (nothing when the scene is full)."""
        n = self.geom_count
        if scene.ngeom + n > scene.maxgeom:
            return
        pos, rot = self.pose(data)
        rgba = self._rgba.copy()
        level = self.thrust_fraction(data)
        discs = slice(self._first_disc, self._first_disc + len(level))
        glow = np.minimum(2 * level, 1.0)[:, None]  # full brightness from half thrust (hover)
        rgba[discs] = _ROTOR_IDLE + glow * (_ROTOR_FULL - _ROTOR_IDLE)
        init, geoms, start = mujoco.mjv_initGeom, scene.geoms, scene.ngeom
        for i, (kind, p, r, size, c) in enumerate(
            zip(self._types, pos, rot.reshape(n, 9), self._size, rgba, strict=True)
        ):
            init(geoms[start + i], kind, size, p, r, c)
        scene.ngeom = start + n
