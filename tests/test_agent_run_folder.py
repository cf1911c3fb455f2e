"""A run folder is never silently overwritten or shared: a non-empty --out needs --resume or
--overwrite, and a folder in use by another training is refused (exit 2, nothing written)."""

import fcntl
import json
import os

import pytest

from cpp_mujoco.agent.run_folder import LOCK_NAME
from cpp_mujoco.cli.main import main
from cpp_mujoco.maps import GridMap
from tests.test_agent_interrupt import TINY_MAP, tiny_args


@pytest.fixture
def tiny_png(tmp_path):
    path = tmp_path / "tiny.png"
    GridMap.from_ascii(TINY_MAP, name="tiny").save(path)
    return str(path)


def _snapshot(folder):
    return {p.name: p.read_bytes() for p in folder.iterdir()}


def test_non_empty_out_is_refused_before_any_write(tmp_path, tiny_png, capsys):
    out = tmp_path / "run"
    out.mkdir()
    (out / "log.csv").write_text("updates\n1000\n")
    before = _snapshot(out)
    code = main(["train", "--out", str(out), *tiny_args(tiny_png), "--total-updates", "2"])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1
    assert f"run folder {out} is not empty (log.csv)" in err and "--resume" in err
    assert _snapshot(out) == before  # not even a lock file


def test_resume_without_checkpoint(tmp_path, tiny_png, capsys):
    stale = tmp_path / "stale"
    stale.mkdir()
    (stale / "best.pt").write_bytes(b"old")
    args = [*tiny_args(tiny_png), "--total-updates", "2", "--resume"]
    assert main(["train", "--out", str(stale), *args]) == 2
    assert "no checkpoint.pt to resume" in capsys.readouterr().err
    assert _snapshot(stale) == {"best.pt": b"old"}
    # an empty or missing folder: a new run, and it says so
    new = tmp_path / "new"
    assert main(["train", "--out", str(new), *args, "--set", "final_eval=true"]) == 0
    assert "no checkpoint.pt in" in capsys.readouterr().out
    assert (new / "checkpoint.pt").is_file()
    # its final evaluation says what produced it
    result = json.loads((new / "final_eval.json").read_text())
    assert result["map_source"] == tiny_png and result["policy"] == "ddqn-tiny"
    assert result["conditions"]["training"]["updates"] == 2
    # the resolved settings beside it, as --config reads them back
    from cpp_mujoco.agent.config import TrainConfig
    from cpp_mujoco.util.settings import read_settings

    stored = TrainConfig(**read_settings(TrainConfig, new / "config.toml"))
    assert stored.total_updates == 2 and stored.final_eval and stored.map == tiny_png


def test_overwrite_replaces_the_old_run(tmp_path, tiny_png):
    out = tmp_path / "run"
    out.mkdir()
    (out / "final_eval.json").write_text("{}")  # the old run's: would pass for this run's
    (out / "notes.txt").write_text("mine")
    args = ["train", "--out", str(out), *tiny_args(tiny_png), "--total-updates", "2"]
    assert main([*args, "--overwrite"]) == 0
    names = {p.name for p in out.iterdir()}
    assert "final_eval.json" not in names  # this run has --no-final-eval
    assert {"checkpoint.pt", "agent.pt", "notes.txt"} <= names  # a user's own file stays
    # the lock is released when the run ends
    with open(out / LOCK_NAME) as f:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    with pytest.raises(SystemExit) as exc:
        main([*args, "--overwrite", "--resume"])
    assert exc.value.code == 2


def test_folder_in_use_is_refused(tmp_path, tiny_png, capsys):
    out = tmp_path / "run"
    out.mkdir()
    with open(out / LOCK_NAME, "w") as lock:  # another training holds the folder
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        lock.write(f"{os.getpid()}\n")
        lock.flush()
        code = main(["train", "--out", str(out), *tiny_args(tiny_png), "--total-updates", "2"])
        err = capsys.readouterr().err
    assert code == 2
    assert f"run folder {out} is in use by process {os.getpid()}" in err
    assert len(err.strip().splitlines()) == 1
    assert [p.name for p in out.iterdir()] == [LOCK_NAME]
