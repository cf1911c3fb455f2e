"""Where bundled data lives: the repository's top-level folders in a checkout, or the copies a
wheel carries under ``cpp_mujoco/_bundled``."""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parents[1]


def bundled_dir(kind: str) -> Path:
    """The folder of bundled ``kind`` data (``"maps"``, ``"assets"``, ``"optimum"``): a
    checkout's top-level folder, else the wheel's copy (never a stranger's folder of that name
    beside an installed package)."""
    root = repository_dir()
    for candidate in ([root / kind] if root else []) + [_PACKAGE / "_bundled" / kind]:
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"bundled folder {kind!r} not found next to {_PACKAGE}")


def repository_dir() -> Path | None:
    """The checkout this package runs from (its ``pyproject.toml`` beside it), else None."""
    root = _PACKAGE.parent
    return root if (root / "pyproject.toml").is_file() else None
