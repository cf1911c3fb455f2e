"""The mission recorder's helpers: its blueprint, the wind probe a flight wears, and the
compaction of a closed recording.

Why apart: the recorder (:mod:`cpp_mujoco.review.recording`) logs; these decide how a recording
is laid out and stored, and the probe is what a caller hooks into a flight to feed the recorder
the wind the flight actually drew.
"""

from __future__ import annotations

import shlex
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import rerun.blueprint as rrb

from cpp_mujoco.util.io import WriteError, atomic_path

COMPACT_TIMEOUT_S = 120.0


def _series(origin: str, name: str, *contents: str) -> rrb.TimeSeriesView:
    return rrb.TimeSeriesView(origin=origin, name=name, contents=list(contents) or "$origin/**")


def blueprint(battery: bool = False, wind: bool = False) -> rrb.Blueprint:
    """The layout: 3D mission, onboard camera and coverage grid, the mission's series, and —
    once they arrive — a column of battery and wind series (each with its unit)."""
    mission = [
        _series("metrics/coverage_ratio", "coverage ratio"),
        _series("metrics/budget", "budget left (units)"),
        _series("metrics", "reward, return", "metrics/reward", "metrics/return"),
    ]
    physics = []
    if battery:
        physics += [
            _series("metrics/energy_j", "battery energy used (J)"),
            _series("metrics/state_of_charge", "state of charge (0-1)"),
            _series("metrics/battery_voltage_v", "battery voltage (V)"),
        ]
    else:
        mission.append(_series("metrics/energy_j", "energy used (J)"))
    if wind:
        physics.append(_series("metrics/wind", "wind at the UAV (m/s)"))
    columns = [
        rrb.Spatial3DView(origin="world", name="mission"),
        rrb.Vertical(
            rrb.Spatial2DView(origin="camera", name="onboard camera"),
            rrb.Spatial2DView(origin="coverage", name="coverage grid"),
        ),
        rrb.Vertical(*mission),
    ]
    if physics:
        columns.append(rrb.Vertical(*physics))
    return rrb.Blueprint(
        rrb.Horizontal(*columns, column_shares=[3, 2, 2, 2][: len(columns)]),
        rrb.TimePanel(timeline="sim_time"),
        collapse_panels=True,
    )


def rerun_cli() -> str:
    """The ``rerun`` command of this environment: the script beside the interpreter (what
    ``pip install rerun-sdk`` puts there; it passes the CLI's exit status on), else on PATH."""
    beside = Path(sys.executable).parent / "rerun"
    found = str(beside) if beside.is_file() else shutil.which("rerun")
    if found is None:
        raise FileNotFoundError("the rerun command is not installed (pip install rerun-sdk)")
    return found


def open_command(path: str | Path) -> str:
    """The command line that opens a recording on this machine: ``rerun PATH`` when that is this
    environment's ``rerun``, else the script beside the interpreter (``.venv/bin/rerun PATH``)."""
    try:
        cli = Path(rerun_cli())
    except FileNotFoundError as e:
        return f"{e}; then: rerun {path}"
    on_path = shutil.which("rerun")
    if on_path and Path(on_path).resolve() == cli.resolve():
        return shlex.join(["rerun", str(path)])
    try:
        shown = str(cli.absolute().relative_to(Path.cwd()))
    except ValueError:  # outside the working directory: the whole path
        shown = str(cli)
    return shlex.join([shown, str(path)])


def compact(path: str | Path) -> bool:
    """Merge a closed recording's chunks (``rerun rrd optimize``, its default profile) and
    replace the file atomically. The streamed file holds one chunk per entity per flush, so its
    chunk count grows with the wall time a mission took (a demo mission rendering two videos
    crossed ``rerun rrd stats``' threshold); compacted, it is a handful per entity. On any
    failure the streamed file stays as it is — complete, only less compact — with a warning."""
    path = Path(path)
    try:
        command = [rerun_cli(), "rrd", "optimize", str(path)]
        with atomic_path(path) as tmp:
            subprocess.run(
                [*command, "-o", str(tmp)],
                capture_output=True,
                check=True,
                timeout=COMPACT_TIMEOUT_S,
            )
            if tmp.stat().st_size == 0:
                raise OSError("rerun rrd optimize wrote nothing")
    except (subprocess.SubprocessError, OSError, WriteError) as exc:
        detail = getattr(exc, "stderr", b"") or b""
        why = detail.decode(errors="replace").strip().splitlines()[-1:] or [type(exc).__name__]
        warnings.warn(f"recording {path} left uncompacted: {why[0][:200]}", stacklevel=2)
        return False
    return True
