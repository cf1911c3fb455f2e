"""The flights recorded from the three physics implementations before they were merged into one.

Why: the scalar ``Flight`` of the single ``MuJoCo-v0`` env, the numpy batched tick and the numba
tick of the vector env fly the same doubles. A backend that replaces them must still fly them, so
every case below is flown through each path with fixed seeds, starts, budgets and actions, and
every number that comes out (pose, observation, reward, flags, info) is kept in
``tests/fixtures/flights.npz``; crash reasons, outcomes and the case descriptions in
``tests/fixtures/flights.json``. ``tests/test_flight_fixtures.py`` replays them to 1e-9 relative.

Record again (only when a change of the flights is intended) with::

    python -m tests.flight_fixtures
"""

from __future__ import annotations

import io
import json
import subprocess
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.grid.actions import EAST, LAND, NORTH, SOUTH, WEST
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.envs.single import BUDGET_EXHAUSTED
from cpp_mujoco.physics.flight import EMERGENCY_LANDING
from cpp_mujoco.physics.power.battery import CUTOFF, OVERLOAD
from cpp_mujoco.util.io import atomic_write_bytes, atomic_write_text

FOLDER = Path(__file__).parent / "fixtures"
ENV_ID = "cpp_mujoco/MuJoCo-v0"
# the paths the flights were recorded through: the single env, the vector env with its numpy
# and its numba tick; each replays through what replaced it (:func:`fly`)
PATHS = ("single", "numpy", "compiled")
RTOL, ATOL = 1e-9, 1e-12
# the open 5×6 map of tests/twin_flights.py: landing strip in the middle row, one no-fly cell
MAP_ROWS = ("TTTTTT", "T..N.T", "TLLLLT", "T....T", "TTTTTT")
MAP = GridMap.from_ascii(list(MAP_ROWS), name="open")
WIND = {"wind_speed": 9.0, "wind_direction": 270.0, "turbulence": "moderate"}
DIVERGED = "numerical divergence (NaN or unstable acceleration)"
FLIPPED = "flipped over"
RECORD = "python -m tests.flight_fixtures"

# three drones from the landing strip: moves each way, a move into the no-fly cell and one off
# the map (hovers), landings, and a drone that never lands
_N, _S, _E, _W, _L = NORTH, SOUTH, EAST, WEST, LAND
WANDER = (
    (_N, _N, _E), (_E, _W, _E), (_N, _S, _W), (_S, _E, _W),
    (_S, _N, _S), (_L, _W, _N), (_E, _L, _W), (_W, _E, _L),
)  # fmt: skip


@dataclass(frozen=True)
class Case:
    """One batch of episodes: drone i starts at ``starts[i]`` with ``budgets[i]`` units from
    ``seeds[i]``, flies ``actions[step][i]``; ``broken``: after the reset drone 0 diverges,
    drone 1 is too fast for the pack, drone 2 is upside down (``twin_flights.break_three``)."""

    name: str
    kwargs: dict[str, Any]
    seeds: tuple[int, ...]
    starts: tuple[tuple[int, int], ...]
    budgets: tuple[int, ...]
    actions: tuple[tuple[int, ...], ...]
    broken: bool = False
    about: str = field(default="", compare=False)

    @property
    def n(self) -> int:
        return len(self.seeds)

    def describe(self) -> dict[str, Any]:
        """The case as plain JSON, to tell a changed case from a drifted flight."""
        return json.loads(json.dumps({**asdict(self), "map": list(MAP_ROWS)}))


_THREE = {"seeds": (11, 12, 13), "starts": ((2, 1), (2, 3), (2, 4)), "actions": WANDER}
CASES = (
    Case("calm", {}, **_THREE, budgets=(12, 12, 3), about="calm air; drone 2 runs out"),
    Case(
        "wind",
        WIND,
        **_THREE,
        budgets=(12, 12, 2),
        about="9 m/s from 270°, moderate turbulence; drone 2 runs out in flight (failsafe)",
    ),  # fmt: skip
    Case("gusts", {"gust_std": 2.0}, **_THREE, budgets=(12, 12, 3), about="2 m/s gusts"),
    Case(
        "failsafe",
        {"battery_cutoff_v": 3.95},
        seeds=(21, 22),
        starts=((2, 2), (2, 3)),
        budgets=(10, 6),
        actions=((_N, _S), (_S, _N), (_N, _S), (_S, _N)),
        about="the pack sags under the cut-off voltage: the failsafe lands where it is",
    ),  # fmt: skip
    Case(
        "failures",
        {},
        seeds=(100, 101, 102, 103),
        starts=((2, 2),) * 4,
        budgets=(10,) * 4,
        actions=tuple((a,) * 4 for a in (_N, _S, _E, _W)),
        broken=True,
        about="divergence, motors cut (a fall), upside-down start; drone 3 flies on",
    ),  # fmt: skip
)


def break_drone(i: int, qpos: np.ndarray, qvel: np.ndarray) -> None:
    """``twin_flights.break_three`` for one drone's free joint (MjData views or state rows)."""
    if i == 0:
        qvel[0] = 1e6
    elif i == 1:
        qvel[0] = 1e12
    elif i == 2:
        qpos[3:7] = (0.0, 1.0, 0.0, 0.0)


@dataclass
class Recording:
    """A case flown through one path: ``arrays[field]`` is (steps + 1, n, …), row 0 the reset;
    a single env's drone that has ended pads its rows (NaN, -1, False; ``stepped`` says which
    are flown). ``reasons[row][i]``: the crash reason; ``outcomes[i]``: how the first episode
    ended ("landed", a crash reason, or None while flying)."""

    arrays: dict[str, np.ndarray]
    reasons: list[list[str | None]]
    outcomes: list[str | None]


def _fields(obs: dict, info: dict, pose: np.ndarray, reward, term, trunc) -> dict[str, Any]:
    """Every number of one step (one drone or all of them): pose (x, y, z, quaternion), each
    observation and info key, reward and flags."""
    out = {"pose": np.array(pose, dtype=float), "reward": reward}
    out.update({f"obs_{k}": v for k, v in obs.items()})
    skip = ("crash_reason",)
    out.update({f"info_{k}": v for k, v in info.items() if not k.startswith("_") and k not in skip})
    out.update(terminated=term, truncated=trunc)
    return {k: np.asarray(v) for k, v in out.items()}


def _pad(template: np.ndarray) -> np.ndarray:
    kind = template.dtype.kind
    fill = {"f": np.nan, "b": False}.get(kind, -1)
    return np.full_like(template, fill)


def fly_single(case: Case) -> Recording:
    """Each drone of ``case`` as its own ``gym.make`` env, until its episode ends."""
    steps = len(case.actions)
    rows: list[list[dict[str, np.ndarray] | None]] = [[None] * case.n for _ in range(steps + 1)]
    reasons: list[list[str | None]] = [[None] * case.n for _ in range(steps + 1)]
    outcomes: list[str | None] = [None] * case.n
    for i in range(case.n):
        env = gym.make(ENV_ID, map=MAP, **case.kwargs)
        data = env.unwrapped.data
        options = {"start": case.starts[i], "budget": case.budgets[i]}
        obs, info = env.reset(seed=case.seeds[i], options=options)
        rows[0][i] = {**_fields(obs, info, data.qpos[:7], 0.0, False, False), "stepped": True}
        if case.broken:  # in the drone's state row: ``data`` is a copy of it
            flight = env.unwrapped.flight
            q, v = flight.cols[:2]
            break_drone(i, flight.state[0, q], flight.state[0, v])
        for step, actions in enumerate(case.actions, start=1):
            obs, reward, term, trunc, info = env.step(int(actions[i]))
            rows[step][i] = {
                **_fields(obs, info, data.qpos[:7], reward, term, trunc),
                "stepped": np.asarray(True),
            }
            reasons[step][i] = info["crash_reason"]
            if term or trunc:
                outcomes[i] = "landed" if info["landed"] else info["crash_reason"]
                break
        env.close()
    arrays = {}
    for key in rows[0][0]:
        pads = [_pad(np.asarray(rows[0][i][key])) for i in range(case.n)]
        arrays[key] = np.stack([
            np.stack([pads[i] if r[i] is None else np.asarray(r[i][key]) for i in range(case.n)])
            for r in rows
        ])  # fmt: skip
    return Recording(arrays, reasons, outcomes)


def fly_vector(case: Case) -> Recording:
    """The drones of ``case`` together in ``gym.make_vec``, every step (an ended episode
    autoresets on the next one, as the vector env does)."""
    env = gym.make_vec(ENV_ID, num_envs=case.n, map=MAP, threads=1, **case.kwargs)
    options = {"start": np.array(case.starts), "budget": np.array(case.budgets)}
    obs, info = env.reset(seed=list(case.seeds), options=options)
    state, (q, v) = env.flight.state, env.flight.cols[:2]
    none = np.zeros(case.n, dtype=bool)
    rows = [_fields(obs, info, state[:, q], np.zeros(case.n), none, none)]
    reasons = [list(info["crash_reason"])]
    if case.broken:
        for i in range(case.n):
            break_drone(i, state[i, q], state[i, v])
    outcomes: list[str | None] = [None] * case.n
    for actions in case.actions:
        obs, reward, term, trunc, info = env.step(np.array(actions))
        rows.append(_fields(obs, info, state[:, q], reward, term, trunc))
        reasons.append(list(info["crash_reason"]))
        for i in np.flatnonzero(term | trunc).tolist():
            if outcomes[i] is None:
                outcomes[i] = "landed" if info["landed"][i] else info["crash_reason"][i]
    env.close()
    arrays = {key: np.stack([r[key] for r in rows]) for key in rows[0]}
    return Recording(arrays, reasons, outcomes)


def fly(case: Case, path: str) -> Recording:
    """``case`` through what flies ``path`` now: the single env, or the vector env (whose one
    compiled tick replaced both recorded ticks)."""
    with np.errstate(all="ignore"):  # the broken drones overflow on their way to the reset
        return fly_single(case) if path == "single" else fly_vector(case)


def compare(recorded: Recording, flown: Recording, where: str) -> None:
    """Assert that ``flown`` is ``recorded``: floats to :data:`RTOL` / :data:`ATOL`, integers,
    flags and strings exactly."""
    assert sorted(flown.arrays) == sorted(recorded.arrays), f"{where}: other fields"
    for key, want in recorded.arrays.items():
        got, at = flown.arrays[key], f"{where}: {key}"
        assert got.shape == want.shape, f"{at}: shape {got.shape} != {want.shape}"
        if want.dtype.kind == "f":
            np.testing.assert_allclose(got, want, rtol=RTOL, atol=ATOL, err_msg=at)
        else:
            assert got.dtype.kind == want.dtype.kind, f"{at}: dtype {got.dtype} != {want.dtype}"
            np.testing.assert_array_equal(got, want, err_msg=at)
    assert flown.reasons == recorded.reasons, f"{where}: crash reasons"
    assert flown.outcomes == recorded.outcomes, f"{where}: outcomes"


def _key(case: str, path: str, name: str) -> str:
    return f"{case}.{path}.{name}"


def load(folder: Path = FOLDER) -> tuple[dict[str, Any], dict[str, Recording]]:
    """The recorded case descriptions and recordings (keyed "case.path"); a clear error where
    the fixture files are missing."""
    files = [folder / "flights.json", folder / "flights.npz"]
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise FileNotFoundError(
            f"flight fixtures missing: {', '.join(missing)}; record them with `{RECORD}`"
        )
    meta = json.loads(files[0].read_text(encoding="utf-8"))
    recordings = {}
    with np.load(files[1]) as npz:
        for case, paths in meta["recordings"].items():
            for path, strings in paths.items():
                prefix = _key(case, path, "")
                arrays = {k[len(prefix) :]: npz[k] for k in npz.files if k.startswith(prefix)}
                recordings[f"{case}.{path}"] = Recording(
                    arrays, strings["reasons"], strings["outcomes"]
                )
    return meta, recordings


def _check(case: Case, flights: dict[str, Recording]) -> None:
    """Refuse to record a case that does not fly what it is meant to pin, or paths that
    disagree (they fly the same doubles until a single env's episode ends)."""
    single, numpy_tick = flights["single"], flights["numpy"]
    compare(numpy_tick, flights["compiled"], f"{case.name}: numpy vs compiled")
    stepped = single.arrays["stepped"]
    for key, want in single.arrays.items():
        if key != "stepped":
            got, at = numpy_tick.arrays[key][stepped], f"{case.name}: single vs numpy, {key}"
            np.testing.assert_allclose(got, want[stepped], rtol=1e-12, atol=1e-9, err_msg=at)
    assert single.outcomes == numpy_tick.outcomes, case.name
    ends = set(single.outcomes)
    wanted = {
        "calm": {"landed", BUDGET_EXHAUSTED},
        "wind": {"landed", EMERGENCY_LANDING},
        "failsafe": {CUTOFF},
        "failures": {DIVERGED, OVERLOAD, FLIPPED},
    }.get(case.name, {"landed"})
    assert wanted <= ends, f"{case.name}: ended {ends}, meant to include {wanted}"
    if case.name == "failsafe":
        assert ends == {CUTOFF}, f"failsafe: {single.outcomes}"


def _git(*args: str) -> str:
    root = Path(__file__).resolve().parents[1]
    return subprocess.run(
        ["git", *args], cwd=root, capture_output=True, text=True, check=True
    ).stdout.strip()


def record(folder: Path = FOLDER) -> dict[str, Any]:
    """Fly every case through every path and write the fixtures; returns the JSON written."""
    import mujoco
    import numba

    arrays: dict[str, np.ndarray] = {}
    recordings: dict[str, dict[str, Any]] = {}
    for case in CASES:
        flights = {path: fly(case, path) for path in PATHS}
        _check(case, flights)
        recordings[case.name] = {}
        for path, flight in flights.items():
            arrays.update({_key(case.name, path, k): a for k, a in flight.arrays.items()})
            recordings[case.name][path] = {"reasons": flight.reasons, "outcomes": flight.outcomes}
    meta = {
        "about": "flights recorded from the single env (scalar Flight) and the vector env "
        "(numpy and numba ticks) before they were merged into one backend",
        "record": RECORD,
        "commit": _git("rev-parse", "HEAD"),
        "cpp_mujoco_modified": bool(_git("status", "--porcelain", "--", "cpp_mujoco")),
        "versions": {
            "numpy": np.__version__,
            "mujoco": mujoco.__version__,
            "numba": numba.__version__,
        },  # fmt: skip
        "tolerance": {"rtol": RTOL, "atol": ATOL},
        "cases": {case.name: case.describe() for case in CASES},
        "recordings": recordings,
    }
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    atomic_write_bytes(folder / "flights.npz", buffer.getvalue())
    atomic_write_text(folder / "flights.json", json.dumps(meta, indent=1) + "\n")
    return meta


if __name__ == "__main__":
    written = record()
    for name, paths in written["recordings"].items():
        print(f"{name:9s}", paths["single"]["outcomes"])
    print(f"wrote {FOLDER / 'flights.npz'} and {FOLDER / 'flights.json'}")
