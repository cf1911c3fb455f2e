"""A map set's rows flown here and over worker processes agree; the checkpoint resumes an
interrupted flight with the rows it holds, and only with rows of the very same flight."""

import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cpp_mujoco.agent import load_agent
from cpp_mujoco.cli.main import main
from cpp_mujoco.map_sets.sets import load_map_set, map_set_names, map_set_spec
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol import map_set_rows
from cpp_mujoco.protocol.map_set_rows import RowTask, fly_rows

BUDGETS = [25, 50, 75]


class Exploding:
    """A policy that fails on its first action (module level: a spawned worker unpickles it)."""

    name = "exploding"

    def act(self, obs):
        raise RuntimeError("the policy broke")


class WaitsForTheFirstRow:
    """Safe greedy that starts only once the checkpoint holds a row: a flight over workers
    that kept its rows only at the end would never let it."""

    name = "waits"

    def __init__(self, checkpoint):
        self.checkpoint, self.planner = checkpoint, make_planner("safe-greedy")

    def act(self, obs):
        deadline = time.monotonic() + 60
        while not self.checkpoint.exists():
            if time.monotonic() > deadline:
                raise RuntimeError("no row was kept while the flight went on")
            time.sleep(0.05)
        return self.planner.act(obs)


class SleepsLong:
    """A policy whose first action takes ten minutes, after marking that it started."""

    name = "sleeps"

    def __init__(self, marker):
        self.marker = marker

    def act(self, obs):
        self.marker.write_text("started")
        time.sleep(600)


def tasks(policies, maps):
    spec = map_set_spec("heldout16-v1")
    config = size_config(16)
    return [
        RowTask(name, policy, m, seed, config, BUDGETS)
        for name, policy in policies
        for m, seed in zip(maps, spec.seeds, strict=False)
    ]


def without_seconds(rows):
    return [{k: v for k, v in r.items() if k != "seconds"} for r in rows]


@pytest.fixture(scope="module")
def maps():
    return load_map_set("heldout16-v1", first=3)


def test_rows_over_workers_equal_the_rows_flown_here(maps):
    policies = [("safe-greedy", make_planner("safe-greedy")), ("general", load_agent("general"))]
    here = fly_rows(tasks(policies, maps))
    over = fly_rows(tasks(policies, maps), workers=2)
    assert without_seconds(over) == without_seconds(here)
    assert [(r["policy"], r["map_digest"]) for r in over] == [
        (n, m.digest) for n, _ in policies for m in maps
    ]
    assert all(r["episodes"] == 3 * m.landing.sum() for r, m in zip(here, maps * 2, strict=True))


def test_an_interrupted_flight_resumes_from_its_checkpoint(maps, tmp_path, monkeypatch):
    path = tmp_path / "rows.json"
    policies = [("safe-greedy", make_planner("safe-greedy"))]
    whole = fly_rows(tasks(policies, maps))
    flown = []
    real = map_set_rows.fly_row

    def fails_on_the_second(task):
        if len(flown) == 1:
            raise OSError("disk full")
        flown.append(task.grid_map.digest)
        return real(task)

    monkeypatch.setattr(map_set_rows, "fly_row", fails_on_the_second)
    with pytest.raises(OSError, match="disk full"):
        fly_rows(tasks(policies, maps), checkpoint=path)
    assert len(json.loads(path.read_text())["rows"]) == 1  # the first row landed and stays
    monkeypatch.setattr(map_set_rows, "fly_row", lambda t: flown.append(t) or real(t))
    flown.clear()
    resumed = fly_rows(tasks(policies, maps), checkpoint=path)
    assert [t.grid_map.digest for t in flown] == [m.digest for m in maps[1:]]  # not the first
    assert without_seconds(resumed) == without_seconds(whole)
    flown.clear()  # another policy is another flight: nothing of the checkpoint is reused,
    other = [("beam-search", make_planner("beam-search"))]  # and the earlier rows are kept
    fly_rows(tasks(other, maps[:1]), checkpoint=path)
    assert len(flown) == 1 and len(json.loads(path.read_text())["rows"]) == 4


def test_rows_over_workers_are_kept_as_they_land(maps, tmp_path):
    path = tmp_path / "rows.json"
    policies = [("safe-greedy", make_planner("safe-greedy")), ("waits", WaitsForTheFirstRow(path))]
    rows = fly_rows(tasks(policies, maps[:1]), workers=2, checkpoint=path)
    assert [r["policy"] for r in rows] == ["safe-greedy", "waits"]


@pytest.mark.parametrize("workers", [None, 2])
def test_a_failing_flight_ends_naming_the_map(maps, workers):
    with pytest.raises(RuntimeError, match="the policy broke") as info:
        fly_rows(tasks([("exploding", Exploding())], maps[:2]), workers=workers)
    assert any("on map gen16-s100000" in note for note in info.value.__notes__)


INTERRUPTED_FLIGHT = """
import sys
from pathlib import Path
from cpp_mujoco.map_sets.sets import load_map_set
from cpp_mujoco.protocol.map_set_rows import fly_rows
from cpp_mujoco.util.signals import interruptible
from tests.test_map_set_rows import SleepsLong, tasks
marker = Path(sys.argv[1])
with interruptible():
    fly_rows(tasks([("sleeps", SleepsLong(marker))], load_map_set("heldout16-v1", first=2)), 2)
"""


def test_an_interrupted_flight_over_workers_stops_them_at_once(tmp_path):
    marker = tmp_path / "started"
    root = Path(__file__).resolve().parent.parent
    flight = subprocess.Popen([sys.executable, "-c", INTERRUPTED_FLIGHT, str(marker)], cwd=root)
    try:
        deadline = time.monotonic() + 120
        while not marker.exists() and flight.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        assert marker.exists(), "the workers never started"
        flight.send_signal(signal.SIGTERM)
        code = flight.wait(timeout=60)  # not the ten minutes the rows in flight would take
    finally:
        flight.kill()
    assert code != 0


@pytest.mark.parametrize("text", ["{not json", '{"rows": {}}', '["rows"]'])
def test_a_broken_checkpoint_is_a_clear_error_and_stays(maps, tmp_path, text):
    path = tmp_path / "rows.json"
    path.write_text(text)
    with pytest.raises(ValueError, match="unreadable checkpoint .* move it away"):
        fly_rows(tasks([("safe-greedy", make_planner("safe-greedy"))], maps[:1]), checkpoint=path)
    assert path.read_text() == text


def test_the_cli_flies_a_set_over_workers_and_removes_its_checkpoint(tmp_path, capsys):
    argv = ["evaluate", "--map-set", "heldout16-v1", "--first", "2", "--planner", "safe-greedy"]
    argv += ["--budget-step", "25"]
    assert main([*argv, "--out", str(tmp_path / "here")]) == 0
    assert main([*argv, "--workers", "2", "--out", str(tmp_path / "over")]) == 0
    assert "resuming" not in capsys.readouterr().out
    here, over = (
        json.loads((tmp_path / d / "grid_heldout16-v1_first2.json").read_text())
        for d in ("here", "over")
    )  # fmt: skip
    assert without_seconds(over["rows"]) == without_seconds(here["rows"])
    assert not list((tmp_path / "over").glob("*.rows.json"))
    mean = np.mean([r["coverage_ratio"] for r in over["rows"]])
    assert over["policies"][0]["mean_coverage_ratio"] == pytest.approx(mean)


def test_the_cli_resumes_from_the_checkpoint_it_is_given(tmp_path, capsys, monkeypatch):
    argv = ["evaluate", "--map-set", "heldout16-v1", "--first", "2", "--planner", "safe-greedy"]
    argv += ["--budget-step", "25", "--out", str(tmp_path), "--checkpoint", str(tmp_path / "c")]
    real, calls = map_set_rows.fly_row, []

    def fails_on_the_second(task):
        calls.append(task)
        if len(calls) == 2:
            raise OSError("disk full")
        return real(task)

    monkeypatch.setattr(map_set_rows, "fly_row", fails_on_the_second)
    assert main(argv) != 0
    assert "disk full" in capsys.readouterr().err
    assert len(json.loads((tmp_path / "c").read_text())["rows"]) == 1
    calls.clear()
    assert main(argv) == 0
    assert "resuming from" in capsys.readouterr().out and len(calls) == 1  # the second map only
    data = json.loads((tmp_path / "grid_heldout16-v1_first2.json").read_text())
    assert [r["map"] for r in data["rows"]] == ["gen16-s1000000", "gen16-s1000001"]
    assert not (tmp_path / "c").exists()
    assert main(["evaluate", "--checkpoint", str(tmp_path / "c"), "--out", str(tmp_path)]) == 2
    assert "--checkpoint needs --map-set" in capsys.readouterr().err


PARTIAL = Path(__file__).resolve().parent.parent / "results" / "partial"


@pytest.mark.parametrize(
    "path", sorted(PARTIAL.glob("*.rows.json")), ids=lambda p: p.name.removesuffix(".rows.json")
)
def test_a_committed_partial_flight_holds_rows_of_its_own_set(path):
    """results/partial/<family>_<set>[_stepN].rows.json: what `results_flights.py` resumes
    from (``_stepN``: a flight of every N-th budget)."""
    rows = map_set_rows.Checkpoint(path).rows
    name = re.sub(r"_step\d+$", "", path.name.removesuffix(".rows.json"))
    spec = next(map_set_spec(s) for s in map_set_names() if name.endswith("_" + s))
    assert rows and all(r["map_digest"] in spec.digests for r in rows.values())
    assert all(r["backend"] == "grid" and r["landing_ratio"] >= 0 for r in rows.values())


def test_a_flight_of_every_nth_budget_gets_files_of_its_own(capsys):
    import runpy

    script = runpy.run_path(str(PARTIAL.parents[1] / "scripts" / "results_flights.py"))
    assert script["set_file"]("value_beam", "city50-v1") == "value_beam_city50-v1.json"
    assert script["set_file"]("map_set", "city50-v1", 10) == "map_set_city50-v1_step10.json"
    with pytest.raises(SystemExit) as stop:
        script["main"](["value-beam", "--map-set", "city50-v1", "--budget-step", "0"])
    assert stop.value.code == 2 and "--budget-step must be a positive integer" in (
        capsys.readouterr().err
    )
