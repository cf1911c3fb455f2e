"""SIGTERM handled like Ctrl-C while a command writes files.

A process killed by SIGTERM's default action runs no ``finally``: its ``.rrd`` lacks the footer
(``rerun rrd verify`` rejects it), its MP4 lacks the index (players reject it) and atomic writes
leave their temporary files behind. Inside :func:`interruptible`, SIGTERM raises
:class:`Terminated` (a ``KeyboardInterrupt``) instead, so the same cleanup runs as for Ctrl-C.

:func:`deferred` marks a short region in which an interrupt waits until the region ends: an
exception raised while a frame is being piped to ffmpeg makes imageio kill ffmpeg, and the video
could then not be finalised.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

EXIT_CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}  # 128 + signal number, as shells report


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived while :func:`interruptible` was active."""

    signum = signal.SIGTERM


_state: dict[str, object] = {"active": False, "depth": 0, "pending": None, "terminating": False}


def exit_code(exc: KeyboardInterrupt) -> int:
    """The conventional exit status for an interrupt: 143 after SIGTERM, 130 after Ctrl-C."""
    return EXIT_CODES[getattr(exc, "signum", signal.SIGINT)]


def _handler(signum: int, frame) -> None:
    if signum == signal.SIGTERM:
        if _state["terminating"]:
            return  # a repeated SIGTERM must not cut the cleanup the first one started
        _state["terminating"] = True
        exc: KeyboardInterrupt = Terminated("terminated (SIGTERM)")
    else:
        exc = KeyboardInterrupt()
    if _state["depth"]:
        _state["pending"] = _state["pending"] or exc
        return
    raise exc


@contextmanager
def interruptible() -> Iterator[None]:
    """Turn SIGINT and SIGTERM into exceptions for the duration (main thread only)."""
    if threading.current_thread() is not threading.main_thread() or _state["active"]:
        yield
        return
    previous = {s: signal.getsignal(s) for s in EXIT_CODES}
    _state.update(active=True, depth=0, pending=None, terminating=False)
    for s in EXIT_CODES:
        signal.signal(s, _handler)
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        _state.update(active=False, depth=0, pending=None, terminating=False)


@contextmanager
def deferred() -> Iterator[None]:
    """An interrupt arriving inside is raised when the region ends (no-op outside
    :func:`interruptible`)."""
    _state["depth"] = int(_state["depth"]) + 1
    try:
        yield
    finally:
        _state["depth"] = int(_state["depth"]) - 1
    pending = _state["pending"]
    if pending is not None and not _state["depth"]:
        _state["pending"] = None
        raise pending  # type: ignore[misc]
