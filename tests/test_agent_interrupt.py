"""Training loses nothing: SIGINT/SIGTERM save a resumable checkpoint, wall-time checkpoints, and a
failing write (file size limit, the way a full disk fails) leaves the previous checkpoint intact."""

import os
import re
import signal
import subprocess
import sys
import time
from subprocess import PIPE

import pytest

from cpp_mujoco.agent.checkpoint import TRAIN_KIND, load_checkpoint
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.cli.main import main
from cpp_mujoco.maps import GridMap

TINY_MAP = ["LL..TT", "L...T.", "..N...", "T.N..T", "......", "TT...L"]
RUN = "import sys; from cpp_mujoco.cli.main import main; sys.exit(main(sys.argv[1:]))"


@pytest.fixture
def tiny_png(tmp_path):
    path = tmp_path / "tiny.png"
    GridMap.from_ascii(TINY_MAP, name="tiny").save(path)
    return str(path)


def tiny_args(png: str) -> list[str]:
    return [
        "--map", png, "--set", "min_budget=6", "--set", "max_budget=10", "--num-envs", "4",
        "--set", "buffer_size=400", "--set", "batch_size=16", "--set", "learning_starts=40",
        "--set", "demo_fraction=0", "--set", "guide_fraction=0", "--set", "lr_warmup_updates=0",
        "--threads", "1", "--set", "final_eval=false", "--set", "checkpoint_every=1000000",
        "--set", "checkpoint_minutes=0",
    ]  # fmt: skip


def _wait_for(path, proc, seconds=90.0):
    deadline = time.monotonic() + seconds
    while not path.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.05)


def test_signals_save_resumable_checkpoints(tmp_path, tiny_png, capsys):
    """SIGTERM → exit 143, SIGINT → 130; each leaves checkpoint.pt + agent.pt, says how to
    resume, and ``--resume`` continues from the saved update count. Both runs go at once."""
    runs = {}
    try:
        for sig in (signal.SIGTERM, signal.SIGINT):
            out = tmp_path / signal.Signals(sig).name
            args = ["train", "--out", str(out), *tiny_args(tiny_png), "--eval-every", "5"]
            cmd = [sys.executable, "-c", RUN, *args, "--total-updates", "1000000"]
            cmd += ["--max-minutes", "2"]
            runs[sig] = (out, args, subprocess.Popen(cmd, stdout=PIPE, stderr=PIPE, text=True))
        for sig, (out, _, proc) in runs.items():
            _wait_for(out / "log.csv", proc)  # the first evaluation: the loop is running
            assert not (out / "checkpoint.pt").exists()  # no periodic checkpoint in this config
            proc.send_signal(sig)
        errors = {sig: proc.communicate(timeout=90)[1] for sig, (_, _, proc) in runs.items()}
    finally:
        for _, _, proc in runs.values():
            proc.kill()
            proc.wait()
    for sig, code in ((signal.SIGTERM, 143), (signal.SIGINT, 130)):
        out, args, proc = runs[sig]
        stderr = errors[sig]
        assert proc.returncode == code, stderr
        state = load_checkpoint(out / "checkpoint.pt")
        updates = state["counters"]["updates"]
        assert state["kind"] == TRAIN_KIND and updates >= 5
        assert load_checkpoint(out / "agent.pt")["network"].keys() == state["network"].keys()
        assert f"stopped by {signal.Signals(sig).name} at update {updates}" in stderr
        assert str(out / "checkpoint.pt") in stderr and "--resume" in stderr
        assert "%|" not in stderr and "Traceback" not in stderr  # no progress bar off a terminal
        capsys.readouterr()
        resumed = main([*args, "--resume", "--total-updates", str(updates + 3), "--no-progress"])
        assert resumed == 0
        assert f"resuming {out / 'checkpoint.pt'} at update {updates}" in capsys.readouterr().out
        assert load_checkpoint(out / "checkpoint.pt")["counters"]["updates"] == updates + 3


def test_resume_refuses_other_learning_settings(tmp_path, tiny_png, capsys):
    out = tmp_path / "run"
    args = ["train", "--out", str(out), *tiny_args(tiny_png), "--eval-every", "1000"]
    assert main([*args, "--total-updates", "2"]) == 0
    before = (out / "checkpoint.pt").read_bytes()
    capsys.readouterr()
    assert main([*args, "--resume", "--total-updates", "4", "--learning-rate", "0.01"]) == 2
    err = capsys.readouterr().err
    assert "learning_rate 0.0005 (stored) vs 0.01 (given)" in err and len(err.splitlines()) == 1
    assert (out / "checkpoint.pt").read_bytes() == before


def test_wall_time_checkpoints(tmp_path, tiny_png):
    def saves(minutes: float) -> int:
        cfg = TrainConfig(
            map=tiny_png, min_budget=6, max_budget=10, num_envs=4, buffer_size=400,
            batch_size=16, learning_starts=40, demo_fraction=0.0, guide_fraction=0.0,
            total_updates=6, eval_every=10**9, checkpoint_every=10**9, final_eval=False,
            threads=1, checkpoint_minutes=minutes,
        )  # fmt: skip
        trainer = Trainer(cfg, tmp_path / f"run{minutes}")
        calls = []
        save = trainer.save
        trainer.save = lambda: (calls.append(trainer.updates), save())
        trainer.run(progress=False)
        return len(calls)

    assert saves(0.0) == 1  # only the final save
    assert saves(1e-7) > 3  # every iteration is past the (tiny) interval


def test_failing_write_keeps_previous_checkpoint(tmp_path, tiny_png, capsys):
    out = tmp_path / "run"
    args = ["train", "--out", str(out), *tiny_args(tiny_png), "--eval-every", "1000"]
    assert main([*args, "--total-updates", "2"]) == 0
    before = (out / "checkpoint.pt").read_bytes()
    names = sorted(os.listdir(out))
    # a real failing write: the file size limit makes write() fail with EFBIG, as ENOSPC would
    limited = (
        "import resource, signal, sys; from cpp_mujoco.cli.main import main; "
        "signal.signal(signal.SIGXFSZ, signal.SIG_IGN); "
        "resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, 100_000)); "
        "sys.exit(main(sys.argv[1:]))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", limited, *args, "--resume", "--total-updates", "4"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    # the first large file the resumed run writes fails (best.pt after the last evaluation, or
    # checkpoint.pt): either way it is named, and nothing it held is lost
    assert re.search(
        rf"cannot write {re.escape(str(out))}/(best|checkpoint)\.pt: file too large", err
    )
    assert "previous file is unchanged" in err
    assert (out / "checkpoint.pt").read_bytes() == before
    assert sorted(os.listdir(out)) == names  # no temporary file left behind


def test_torch_write_failure_is_named(tmp_path):
    """torch.save into a path reports a failed write as "unexpected pos"; say what it means."""
    from cpp_mujoco.util.io import WriteError, atomic_path

    torch_words = "[enforce fail at inline_container.cc:672] . unexpected pos 576 vs 534"
    with pytest.raises(WriteError, match=r"write failed \(disk full or file size limit reached\)"):
        with atomic_path(tmp_path / "x.pt"):
            raise RuntimeError(torch_words)
    assert list(tmp_path.iterdir()) == []
