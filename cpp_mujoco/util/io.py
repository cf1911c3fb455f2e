"""Files: every write is atomic, and every name-or-path argument resolves one way.

* :func:`atomic_path` / :func:`atomic_write_bytes` / :func:`atomic_write_text` write to a unique
  temporary file beside the target, fsync it and ``os.replace`` it over the target, so a crash, a
  kill or a full disk never leaves half a file and never touches the previous version. A failed
  write removes the temporary file and raises :class:`WriteError` with a one-line message.
* :func:`resolve_named_file` turns ``"A"`` (a bundled name) or ``"path/to/file.png"`` (a file)
  into a :class:`Resolved` path, name and origin — maps and agents use it alike.
"""

from __future__ import annotations

import errno
import json
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, is_dataclass
from pathlib import Path
from typing import Any

import numpy as np


class WriteError(OSError):
    """A file could not be written; the target (if it existed) is unchanged."""


def _reason(exc: BaseException, folder: Path) -> str:
    """One line saying why a write failed; a full disk is named as such."""
    code = getattr(exc, "errno", None)
    if code in (errno.ENOSPC, errno.EDQUOT):
        return "no space left on device"
    if code == errno.EFBIG:
        return "file too large (file size limit reached)"
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    try:  # libraries (torch, ffmpeg) report a full disk in their own words
        if os.statvfs(folder).f_bavail == 0:
            return "no space left on device"
    except OSError:
        pass
    if isinstance(exc, RuntimeError) and any(
        m in str(exc) for m in ("unexpected pos", "file write failed")
    ):  # torch's stream writer hides the OS error behind its own words
        return "write failed (disk full or file size limit reached)"
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[-1][:200]}" if text else type(exc).__name__


@contextmanager
def atomic_path(path: str | os.PathLike, *, fsync: bool = True) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` to write to; on success it replaces ``path``.

    For libraries that want a file name (matplotlib, PIL, ffmpeg). The temporary name keeps the
    target's suffix, so format detection by extension works.
    """
    path = Path(path)
    if path.is_dir():
        raise WriteError(f"cannot write {path}: it is a folder")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(
            dir=path.parent, prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}"
        )
        os.close(fd)
    except OSError as exc:
        raise WriteError(f"cannot write {path}: {_reason(exc, path.parent)}") from None
    tmp = Path(tmp_name)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; results are for everyone
        if fsync:
            with open(tmp, "rb") as f:
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        wrap = isinstance(exc, (OSError, RuntimeError)) and not isinstance(exc, WriteError)
        reason = _reason(exc, path.parent) if wrap else ""  # before removing frees the space
        tmp.unlink(missing_ok=True)
        if wrap:
            raise WriteError(
                f"cannot write {path}: {reason}; any previous file is unchanged"
            ) from None
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def json_default(value: Any) -> Any:
    """``json.dumps(default=...)`` for results: numpy scalars/arrays and dataclasses (options
    given as numpy values, configs) become plain JSON; anything else is an error."""
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    if is_dataclass(value) and not isinstance(value, type):
        return asdict(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


# ----------------------------------------------------------------------------- name or path
@dataclass(frozen=True)
class Resolved:
    """Where a name-or-path argument points: ``bundled`` files are known by ``name``; a user's
    file by its path (``name`` is its stem, which may equal a bundled name)."""

    path: Path
    name: str
    bundled: bool


def json_plain(value: Any) -> Any:
    """``value`` as plain JSON types (what it reads back as after :func:`json_default`)."""
    return json.loads(json.dumps(value, default=json_default))


def is_path_like(spec: str | os.PathLike, suffix: str) -> bool:
    """A path is anything with a folder separator or the kind's suffix; the rest are names."""
    text = os.fspath(spec)
    return (
        isinstance(spec, os.PathLike)
        or "/" in text
        or os.sep in text
        or (text.lower().endswith(suffix))
    )


def resolve_named_file(
    spec: str | os.PathLike,
    *,
    bundled: Path,
    suffix: str,
    kind: str,
    error: type[Exception] = ValueError,
) -> Resolved:
    """Resolve ``spec`` to a bundled ``kind`` (``bundled/<spec><suffix>``) or to a user's file.

    Raises ``error`` with the bundled names for an unknown name, and with the path for a file
    that is missing or a folder.
    """
    text = os.fspath(spec)
    if not text:
        raise error(f"empty {kind} name")
    if is_path_like(spec, suffix):
        path = Path(text).expanduser()
        if path.is_dir():
            raise error(f"{kind} {text!r} is a folder, not a {suffix} file")
        if not path.is_file():
            raise error(f"no such {kind} file: {text}")
        return Resolved(path.resolve(), path.stem, bundled=False)
    if Path(text).expanduser().is_dir():
        raise error(f"{kind} {text!r} is a folder, not a {suffix} file")
    candidate = bundled / f"{text}{suffix}"
    if not candidate.is_file():
        names = sorted(p.name[: -len(suffix)] for p in bundled.glob(f"*{suffix}"))
        raise error(
            f"unknown {kind} {text!r}; bundled: {', '.join(names) or 'none'} "
            f"(or give the path of a {suffix} file)"
        )
    return Resolved(candidate.resolve(), text, bundled=True)
