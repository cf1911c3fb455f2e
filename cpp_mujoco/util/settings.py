"""A dataclass's settings from a TOML file and ``KEY=VALUE`` overrides, and back to TOML.

Training has dozens of settings; a person names the few that matter on the command line and
keeps the rest in a file (``--config run.toml``) or one ``--set key=value`` at a time. The
dataclass stays the one source of every default: a file or an override names only what differs,
every key is checked against the dataclass's fields, every value against the field's type, and
the resolved settings are written back as TOML beside the run (:func:`to_toml`), where they can
be read again (:func:`read_settings`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import tomllib
import typing
from pathlib import Path
from typing import Any

_TRUE, _FALSE = ("true", "yes", "on", "1"), ("false", "no", "off", "0")


class SettingsError(ValueError):
    """A settings file or override the dataclass cannot take."""


def with_options(cls: type, config: Any, what: str, **options: Any) -> Any:
    """``config`` (default: ``cls()``) with ``options`` replaced; an option that is not a field
    of ``cls`` is a ``ValueError`` naming the known ones (``what``: whose options they are)."""
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(options) - known)
    if unknown:
        raise ValueError(f"unknown {what} option(s) {unknown}; known: {sorted(known)}")
    return dataclasses.replace(config or cls(), **options)


def check_ranges_and_chances(
    config: Any, ranges: tuple[str, ...], chances: tuple[str, ...]
) -> None:
    """A generator config's fields as it reads them: lists (from JSON) become tuples, each of
    ``ranges`` must be a (low, high) pair with 0 <= low <= high, each of ``chances`` lie in 0..1;
    a ``ValueError`` names the first field that does not."""
    for name in (*ranges, *chances):
        value = getattr(config, name)
        if isinstance(value, list):
            object.__setattr__(config, name, value := tuple(value))
        if name in ranges and not (
            isinstance(value, tuple) and len(value) == 2 and 0 <= value[0] <= value[1]
        ):
            raise ValueError(f"{name} must be a range (low, high), got {value!r}")
        if name in chances and not 0.0 <= value <= 1.0:
            raise ValueError(f"{name} is a probability in 0..1, got {value!r}")


@functools.cache
def _kinds(cls: type) -> dict[str, tuple[type, type | None]]:
    """Each field's (kind, element kind): ``int``, ``float``, ``bool``, ``str`` or ``tuple``
    (with its element's kind)."""
    hints = typing.get_type_hints(cls)
    out: dict[str, tuple[type, type | None]] = {}
    for f in dataclasses.fields(cls):
        hint = hints[f.name]
        if typing.get_origin(hint) is tuple:
            out[f.name] = (tuple, typing.get_args(hint)[0])
        else:
            out[f.name] = (hint, None)
    return out


def _scalar(kind: type, value: Any, where: str) -> Any:
    """``value`` (a TOML value or the text of an override) as ``kind``."""
    if isinstance(value, str) and kind is not str:
        text = value.strip()
        if kind is bool:
            if text.lower() in _TRUE + _FALSE:
                return text.lower() in _TRUE
            raise SettingsError(f"{where}: expected true or false, got {value!r}")
        try:
            value = int(text) if kind is int else float(text)
        except ValueError:
            raise SettingsError(f"{where}: expected {kind.__name__}, got {value!r}") from None
    if kind is bool and not isinstance(value, bool):
        raise SettingsError(f"{where}: expected true or false, got {value!r}")
    if kind is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise SettingsError(f"{where}: expected an integer, got {value!r}")
    if kind is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SettingsError(f"{where}: expected a number, got {value!r}")
        value = float(value)
        if math.isnan(value):
            raise SettingsError(f"{where}: not a number (NaN)")
    if kind is str and not isinstance(value, str):
        raise SettingsError(f"{where}: expected text, got {value!r}")
    return value


def coerce(cls: type, name: str, value: Any, where: str = "") -> Any:
    """``value`` for field ``name`` of ``cls``; ``SettingsError`` naming the key otherwise."""
    kinds = _kinds(cls)
    where = f"{where}{name}"
    if name not in kinds:
        raise SettingsError(f"unknown setting {name!r}; known: {', '.join(kinds)}")
    kind, element = kinds[name]
    if kind is not tuple:
        return _scalar(kind, value, where)
    if isinstance(value, str):
        value = [v for v in value.split(",") if v.strip()]
    if not isinstance(value, (list, tuple)):
        raise SettingsError(f"{where}: expected a list, got {value!r}")
    return tuple(_scalar(element, v, where) for v in value)


def read_settings(cls: type, path: str | Path) -> dict[str, Any]:
    """The settings of a TOML file (its top-level keys: fields of ``cls``), checked."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SettingsError(f"{path}: no such settings file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise SettingsError(f"{path}: not a TOML file ({e})") from None
    return {k: coerce(cls, k, v, f"{path}: ") for k, v in data.items()}


def parse_override(cls: type, text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` (``learning_rate=3e-4``, ``sizes=16,32``, ``final_eval=false``)."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise SettingsError(f"--set {text!r}: expected KEY=VALUE")
    key = key.strip().replace("-", "_")
    return key, coerce(cls, key, value, "--set ")


def to_toml(config: Any) -> str:
    """A dataclass's settings as TOML, every field in its order (the resolved settings of a
    run: read back by :func:`read_settings`, they give the same dataclass)."""
    lines = []
    for f in dataclasses.fields(config):
        lines.append(f"{f.name} = {_toml_value(getattr(config, f.name))}")
    return "\n".join(lines) + "\n"


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"')
        return f'"{escaped}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML form for {value!r}")
