"""Rerun recordings (.rrd) of a mission, for either backend.

What a reviewer sees: the map in 3D (zones in the paper's colours, no-fly volumes), the UAV's
pose and trajectory, the camera footprint on the ground, the waypoint each action commanded (a
marker over the cell it goes to, from the moment the action starts), the wind acting on the UAV
(an arrow at the UAV and east / north / speed series, where the caller passes the wind), the
coverage grid over time, the onboard camera frames, and budget / reward / coverage and — in
physics — the battery (energy used, state of charge, terminal voltage) as time series, on a
``sim_time`` timeline and a ``step`` timeline (one tick per grid action), laid out by a
blueprint with the battery and wind views (from the start where the caller says they will
come, else from their first values).

The file is written as the mission goes, in chunks of a few seconds of wall time (one chunk per
entity per flush: flushing every step made a mission ~1,000 tiny chunks). Closing it — also on
Ctrl-C or SIGTERM (:mod:`cpp_mujoco.util.signals`) — writes the footer ``rerun rrd verify`` wants; a
recording cut by SIGKILL keeps what was flushed and can be repaired (see docs/guide.md). A mission
closed normally is then compacted (``rerun rrd optimize``, atomically), so its chunk count no
longer grows with the wall time the flight took and ``rerun rrd stats`` finds nothing to merge.
Each recording has its own random recording id, so two opened together stay two recordings.
"""

from __future__ import annotations

import os
import time
import uuid
from datetime import timedelta
from pathlib import Path

import numpy as np
import rerun as rr

from cpp_mujoco.grid.actions import ACTION_NAMES, LAND
from cpp_mujoco.grid.image import grid_image, zone_colors
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.review.recording_tools import blueprint, compact
from cpp_mujoco.util.io import WriteError, _reason

__all__ = ["MissionRecorder", "batcher_config", "blueprint"]

_WORLD = PhysicsConfig()  # the default scale (a MuJoCo mission passes its own)

NFZ_RGBA = (255, 30, 30, 60)
FOOTPRINT_RGBA = (255, 220, 0, 255)
TRAJECTORY_RGBA = (255, 40, 40, 255)
WAYPOINT_RGBA = (0, 200, 255, 255)
WIND_RGBA = (60, 120, 255, 255)
WIND_ARROW_S = 0.5  # arrow length per m/s of wind: 12 m/s is 6 m, 1.5 cells of 4 m
METRICS = ("energy_j", "budget", "reward", "return", "coverage_ratio")
# the LiPo pack's series, from the MuJoCo backend's info (the grid has no battery): their views
# join the blueprint with the first step that carries them, so grid recordings stay as they were
BATTERY_METRICS = ("state_of_charge", "battery_voltage_v")
# the wind at the UAV (world frame: x east, y north), m/s; speed is the norm of the 3D vector.
# One entity with three series: one chunk per flush instead of three
WIND_SERIES = ("east", "north", "speed")
WIND_SERIES_RGBA = [(230, 90, 40, 255), (40, 150, 60, 255), (40, 40, 40, 255)]
APPLICATION_ID = "cpp_mujoco"
FLUSH_TIMEOUT_S = 30.0  # a flush that has not finished by then has failed
FLUSH_SECONDS = 5.0  # wall time between flushes: about what a SIGKILL loses of a mission


def batcher_config(flush_seconds: float = FLUSH_SECONDS) -> rr.ChunkBatcherConfig:
    """Flush on time only (byte and row thresholds far above one mission's data)."""
    return rr.ChunkBatcherConfig(
        flush_tick=timedelta(seconds=flush_seconds),
        flush_num_bytes=256 * 2**20,
        flush_num_rows=2**40,
    )


class MissionRecorder:
    """Writes one mission to ``path``. Call :meth:`log_pose` at the camera rate,
    :meth:`log_camera` for onboard frames, :meth:`log_step` after every grid action.
    ``properties`` (policy, backend, conditions) are stored with the map's identity as the
    recording's ``mission`` property. ``battery`` / ``wind``: lay out their views from the
    start (default: battery for a ``mujoco`` backend); otherwise a view joins the layout when
    its first value arrives."""

    def __init__(
        self,
        path: str | os.PathLike,
        grid_map: GridMap,
        cell_size: float = _WORLD.cell_size,
        altitude: float = _WORLD.altitude,
        name: str = "mission",
        flush_seconds: float | None = None,
        properties: dict[str, object] | None = None,
        battery: bool | None = None,
        wind: bool = False,
    ):
        self.path = Path(path)
        if self.path.is_dir():
            raise OSError(f"cannot write recording {self.path}: it is a folder")
        try:  # streamed, not atomic: a cut run keeps what was flushed (see the module doc)
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.path.touch()
        except OSError as e:
            raise OSError(f"cannot write recording {self.path}: {e.strerror}") from e
        self.map, self.cell_size, self.altitude = grid_map, cell_size, altitude
        self.recording_id = str(uuid.uuid4())
        self.flush_seconds = flush_seconds or FLUSH_SECONDS
        self.rec = rr.RecordingStream(
            APPLICATION_ID,
            recording_id=self.recording_id,
            batcher_config=batcher_config(self.flush_seconds),
        )
        self.rec.save(str(self.path))
        self.rec.send_recording_name(f"{name} on map {grid_map.label}")
        identity = {k: v for k, v in grid_map.identity().items() if k != "map_shape"}
        mission = {**identity, **(properties or {})}  # what decided the numbers shown
        self.rec.send_property("mission", rr.AnyValues(**{k: str(v) for k, v in mission.items()}))
        self._flushed = time.monotonic()
        self.trajectory: list[np.ndarray] = []
        self.step = 0
        self.total_reward = 0.0
        self.battery = self.wind = False  # their series' styles logged
        self._views: tuple[bool, bool] | None = None  # (battery, wind) in the sent blueprint
        if battery is None:  # a MuJoCo mission has a battery: its views from the start
            battery = (properties or {}).get("backend") == "mujoco"
        self._show(battery, wind)
        self._action_start: float | None = None  # sim time the current action began
        self._log_scene()

    def _show(self, battery: bool, wind: bool) -> None:
        """Send the blueprint with these views, unless the one sent has them already: each
        send is a few dozen chunks, so a mission whose series are known up front sends one."""
        views = self._views or (False, False)
        wanted = (views[0] or battery, views[1] or wind)
        if wanted != self._views:
            self._views = wanted
            self.rec.send_blueprint(blueprint(*wanted))

    # ------------------------------------------------------------------ static scene
    def _log_scene(self) -> None:
        m, cs = self.map, self.cell_size
        centers = GridGeometry.of(m, cs).centers()  # the arena's cells, row-major
        colors = zone_colors(m).reshape(-1, 3)
        n = centers.shape[0]
        self.rec.log(
            "world/ground",
            rr.Boxes3D(
                centers=np.c_[centers, np.zeros(n)],
                half_sizes=np.tile([0.48 * cs, 0.48 * cs, 0.01], (n, 1)),
                colors=colors,
                fill_mode="solid",
            ),
            static=True,
        )
        nfz = m.nfz.reshape(-1)
        if nfz.any():
            height = 2 * self.altitude
            self.rec.log(
                "world/no_fly",
                rr.Boxes3D(
                    centers=np.c_[centers[nfz], np.full(nfz.sum(), height / 2)],
                    half_sizes=np.tile([cs / 2, cs / 2, height / 2], (int(nfz.sum()), 1)),
                    colors=NFZ_RGBA,
                    fill_mode="solid",
                ),
                static=True,
            )
        arm = 0.25
        self.rec.log(
            "world/uav/body",
            rr.Boxes3D(
                half_sizes=[[arm, 0.02, 0.02], [0.02, arm, 0.02], [0.08, 0.08, 0.04]],
                colors=[(40, 40, 40), (40, 40, 40), (250, 120, 0)],
                fill_mode="solid",
            ),
            static=True,
        )
        for metric in METRICS:
            self.rec.log(f"metrics/{metric}", rr.SeriesLines(names=metric), static=True)

    # ------------------------------------------------------------------ time
    def _at(self, time_s: float) -> None:
        self.rec.set_time("sim_time", duration=float(time_s))
        self.rec.set_time("step", sequence=self.step)

    # ------------------------------------------------------------------ per sample
    def log_pose(
        self,
        time_s: float,
        position: np.ndarray,
        quaternion_wxyz: np.ndarray = (1.0, 0.0, 0.0, 0.0),
        footprint_xy: np.ndarray | None = None,
        wind: np.ndarray | None = None,
    ) -> None:
        """The UAV's pose, the camera footprint polygon (k, 2) on the ground and, given
        ``wind`` (m/s, world frame: x east, y north, z up), the wind arrow and series."""
        self._at(time_s)
        if self._action_start is None:
            self._action_start = float(time_s)
        w, x, y, z = (float(v) for v in quaternion_wxyz)
        position = np.asarray(position, dtype=float)
        self.rec.log(
            "world/uav",
            rr.Transform3D(translation=position, quaternion=rr.Quaternion(xyzw=[x, y, z, w])),
        )
        self.trajectory.append(position)
        if footprint_xy is not None:
            ring = np.asarray(footprint_xy, dtype=float)
            ring = np.c_[np.r_[ring, ring[:1]], np.full(len(ring) + 1, 0.05)]
            self.rec.log(
                "world/footprint", rr.LineStrips3D([ring], colors=FOOTPRINT_RGBA, radii=0.06)
            )
        if wind is not None:
            self._log_wind(position, np.asarray(wind, dtype=float))

    def _log_wind(self, position: np.ndarray, wind: np.ndarray) -> None:
        """The wind as an arrow at the UAV and as east / north / speed series."""
        if not self.wind:
            self.wind = True
            self.rec.log(
                "metrics/wind",
                rr.SeriesLines(names=WIND_SERIES, colors=WIND_SERIES_RGBA),
                static=True,
            )
            self._show(battery=False, wind=True)
        self.rec.log(
            "world/wind",
            rr.Arrows3D(
                origins=[position], vectors=[wind * WIND_ARROW_S], colors=WIND_RGBA, radii=0.08
            ),
        )
        self.rec.log("metrics/wind", rr.Scalars([wind[0], wind[1], float(np.linalg.norm(wind))]))

    def log_camera(self, time_s: float, image: np.ndarray) -> None:
        self._at(time_s)
        self.rec.log("camera/image", rr.Image(image).compress(jpeg_quality=80))

    def log_step(
        self,
        time_s: float,
        action: int,
        reward: float,
        info: dict,
        coverage: np.ndarray,
        position_cell: int,
    ) -> None:
        """After a grid action: the waypoint it commanded (logged at the time it began),
        coverage grid, trajectory so far, metrics, an event line. ``position_cell``: the flat
        cell the action left the UAV at — the commanded cell (the env's safety decision)."""
        self._log_waypoint(action, info, position_cell)
        self._action_start = float(time_s)
        self.step += 1
        self._at(time_s)
        self.total_reward += reward
        self.rec.log("coverage", rr.Image(grid_image(self.map, coverage, position_cell, scale=8)))
        if len(self.trajectory) >= 2:
            self.rec.log(
                "world/trajectory",
                rr.LineStrips3D([np.stack(self.trajectory)], colors=TRAJECTORY_RGBA, radii=0.05),
            )
        values = {
            "energy_j": info.get("energy_used_j", float("nan")),
            "budget": info["budget"],
            "reward": reward,
            "return": self.total_reward,
            "coverage_ratio": info["coverage_ratio"],
        }
        if not self.battery and all(m in info for m in BATTERY_METRICS):
            self.battery = True
            for metric in BATTERY_METRICS:
                self.rec.log(f"metrics/{metric}", rr.SeriesLines(names=metric), static=True)
            self._show(battery=True, wind=False)
        if self.battery:
            values.update({m: info.get(m, float("nan")) for m in BATTERY_METRICS})
        for metric, value in values.items():
            if np.isfinite(value):
                self.rec.log(f"metrics/{metric}", rr.Scalars(float(value)))
        outcome = "rejected" if info["rejected"] else "accepted"
        text = f"step {self.step}: {ACTION_NAMES[action]} {outcome}, cell {info['position']}"
        if info.get("landed"):
            text += ", landed"
        if info.get("crashed"):
            text += f", CRASHED ({info.get('crash_reason') or 'budget exhausted'})"
        self.rec.log("events", rr.TextLog(text, level="WARN" if info.get("crashed") else "INFO"))
        if time.monotonic() - self._flushed >= self.flush_seconds:
            self._flush()  # to disk now: the batcher's own tick may wait much longer
            self._flushed = time.monotonic()

    def _log_waypoint(self, action: int, info: dict, cell: int) -> None:
        """A marker over the cell the action commanded — on the ground for a landing — at the
        sim time the action began, so it shows while the UAV flies there."""
        row, col = divmod(int(cell), self.map.shape[1])
        x, y = GridGeometry.of(self.map, self.cell_size).cell_center(row, col)
        lands = info.get("landed") or (action == LAND and not info.get("rejected"))
        what = ACTION_NAMES[action] + (" rejected: hold" if info.get("rejected") else "")
        if info.get("guard_active"):  # the return guard flew its own action instead
            what = f"guard: home (policy: {what})"
        self.rec.set_time("sim_time", duration=self._action_start or 0.0)
        self.rec.set_time("step", sequence=self.step)
        self.rec.log(
            "world/waypoint",
            rr.Points3D(
                [[x, y, 0.1 if lands else self.altitude]],
                radii=0.35,
                colors=WAYPOINT_RGBA,
                labels=f"{self.step + 1}: {what} → ({row}, {col})",
            ),
        )

    def close(self, interrupted: str | None = None) -> Path:
        """Flush and write the footer. ``interrupted``: why the mission stopped early; logged as
        the last event, so the recording says it is not the whole mission."""
        if interrupted:
            self.rec.set_time("step", sequence=self.step)
            self.rec.log(
                "events",
                rr.TextLog(
                    f"mission interrupted ({interrupted}); recording ends here", level="ERROR"
                ),
            )
        self._flush()  # a WriteError leaves the stream connected: rerun's disconnect would wait
        self.rec.disconnect()  # forever for a file sink that can no longer write
        if not interrupted:  # an interrupted run exits now; its file is complete as it is
            compact(self.path)
        return self.path

    def _flush(self) -> None:
        """Flush to the file; a failed write (full disk, size limit) is a one-line WriteError —
        rerun's own flush would wait forever for a writer that cannot write."""
        try:
            self.rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
        except RuntimeError as exc:  # rerun's file writer died (full disk, file size limit)
            why = _reason(exc, self.path.parent)
            raise WriteError(f"cannot write recording {self.path}: {why}") from None
        try:
            full = os.statvfs(self.path.parent).f_bavail == 0
        except OSError:
            full = False
        if full:
            raise WriteError(
                f"cannot write recording {self.path}: no space left on device; the recording "
                "holds the mission up to the last flush"
            )
