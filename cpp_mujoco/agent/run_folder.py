"""What a training run holds while it runs: its folder (guarded and locked) and the stop signals.

* :func:`claim_run_folder` refuses to start a new run over an old one (``--resume`` continues it,
  ``--overwrite`` replaces it) and holds an exclusive ``flock`` on ``<out>/.lock`` for the whole
  run, so two trainings can never interleave their files in one folder. The kernel drops the lock
  when the process dies, even by ``kill -9``: a stale ``.lock`` file never blocks a later run.
* :class:`StopSignals` turns SIGINT/SIGTERM into a flag the training loop polls between updates,
  so it can save a resumable checkpoint before it exits.
"""

from __future__ import annotations

import errno
import fcntl
import os
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

LOCK_NAME = ".lock"
# the files a run writes; --overwrite removes these (and only these) before the new run starts
RUN_FILES = (
    "checkpoint.pt", "agent.pt", "best.pt", "log.csv", "training.png", "final_eval.json",
    "config.toml",
)  # fmt: skip


class RunFolderError(ValueError):
    """The run folder cannot be used as asked; the message says why and what to pass instead."""


def _contents(out: Path) -> list[str]:
    if not out.exists():
        return []
    if not out.is_dir():
        raise RunFolderError(f"--out {out} is a file, not a folder")
    return sorted(p.name for p in out.iterdir() if p.name != LOCK_NAME)


def check_run_folder(out: Path, *, resume: bool, overwrite: bool) -> None:
    """Refuse ``out`` when it holds files this run would silently mix with or overwrite."""
    if resume and overwrite:
        raise RunFolderError("--resume and --overwrite exclude each other")
    names = _contents(out)
    if not names or overwrite:
        return
    shown = ", ".join(names[:4]) + (" …" if len(names) > 4 else "")
    if not resume:
        raise RunFolderError(
            f"run folder {out} is not empty ({shown}); pass --resume to continue its run, "
            "--overwrite to replace it, or another --out"
        )
    if "checkpoint.pt" not in names:
        raise RunFolderError(
            f"--resume: run folder {out} holds files ({shown}) but no checkpoint.pt to resume; "
            "pass --overwrite to start a new run there"
        )


def _holder(fd: int) -> str:
    try:
        pid = os.pread(fd, 32, 0).decode().strip()
    except (OSError, UnicodeDecodeError):
        pid = ""
    return f"process {pid}" if pid.isdigit() else "another process"


@contextmanager
def claim_run_folder(
    out: str | os.PathLike, *, resume: bool = False, overwrite: bool = False
) -> Iterator[Path]:
    """Check ``out`` (see :func:`check_run_folder`), lock it for the ``with`` block, and with
    ``overwrite`` remove the previous run's files. Nothing is written when the folder is refused.
    """
    out = Path(out)
    check_run_folder(out, resume=resume, overwrite=overwrite)  # before writing anything
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd = os.open(out / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise RunFolderError(f"cannot use run folder {out}: {exc.strerror}") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise RunFolderError(f"cannot lock run folder {out}: {exc.strerror}") from None
            raise RunFolderError(f"run folder {out} is in use by {_holder(fd)}") from None
        # the lock file holds the holder's pid for the message above; it is written in place
        # (not through cpp_mujoco.util.io's atomic replace), because replacing it would drop the
        # lock
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        except OSError as exc:
            raise RunFolderError(f"cannot use run folder {out}: {exc.strerror}") from None
        check_run_folder(out, resume=resume, overwrite=overwrite)  # again, now under the lock
        if overwrite:
            for name in RUN_FILES:
                (out / name).unlink(missing_ok=True)
        yield out
    finally:
        os.close(fd)  # releases the lock


class TrainingInterrupted(Exception):
    """SIGINT/SIGTERM stopped the run after it saved a resumable ``checkpoint``."""

    def __init__(self, signum: int, updates: int, checkpoint: Path):
        self.signum, self.updates, self.checkpoint = signum, updates, checkpoint
        self.signal_name = signal.Signals(signum).name
        super().__init__(
            f"stopped by {self.signal_name} at update {updates}; resumable checkpoint: {checkpoint}"
        )


class StopSignals:
    """While active, SIGINT/SIGTERM set ``received`` (the signal number) instead of killing the
    process; a second signal raises ``KeyboardInterrupt`` at once. The previous handlers come
    back on exit. Outside the main thread (where Python cannot install handlers) it does nothing.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.received: int | None = None
        self._previous: dict[int, object] = {}

    def _handle(self, signum: int, frame) -> None:
        if self.received is not None:
            raise KeyboardInterrupt(f"second signal ({signal.Signals(signum).name})")
        self.received = signum

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()
