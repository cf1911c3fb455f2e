"""The training commands' settings: a few options, a TOML file and ``--set`` overrides.

``train`` and ``train-general`` show as options only the settings a person changes run by run;
every other field of their config is set in a TOML file (``--config run.toml``: keys are the
config's field names) or one at a time (``--set learning_rate=3e-4``). A file is read first,
then the ``--set`` overrides, then the options; the config's dataclass gives every default
(:mod:`cpp_mujoco.util.settings`). ``--list-settings`` prints every setting with its default
and one line on what it does; the resolved settings land in the run folder as ``config.toml``.
"""

from __future__ import annotations

import argparse
import re
import shlex
from collections.abc import Callable, Sequence
from typing import Any

from cpp_mujoco.util.settings import SettingsError, coerce, parse_override, read_settings


def flag(name: str) -> str:
    return "--" + name.replace("_", "-")


class ListSettings(argparse.Action):
    """``--list-settings``: every setting, its default and its line, then exit."""

    def __init__(self, option_strings, dest, lines: Callable[[], str], **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)
        self.lines = lines

    def __call__(self, parser, namespace, values, option_string=None):
        print(self.lines(), end="")
        parser.exit(0)


def add_settings_options(
    p: argparse.ArgumentParser,
    cls: type,
    shown: Sequence[str],
    helps: dict[str, str],
    allowed: Sequence[str],
    choices: dict[str, Sequence[str]] | None = None,
) -> None:
    """``--config``, ``--set``, ``--list-settings`` and one option per ``shown`` field."""
    defaults = cls()
    p.add_argument(
        "--config", metavar="FILE",
        help="TOML file of settings (keys: the names --list-settings prints); --set and the "
        "options override it",
    )  # fmt: skip
    p.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", dest="settings",
        help="one setting, repeatable (--set learning_rate=3e-4 --set sizes=16,32)",
    )  # fmt: skip

    def lines() -> str:
        out = [f"{cls.__name__} settings (default, then what it does):"]
        for name in allowed:
            value = getattr(defaults, name)
            out.append(f"  {name} = {value!r}\n      {helps[name]}")
        return "\n".join(out) + "\n"

    p.add_argument(
        "--list-settings", action=ListSettings, lines=lines,
        help="print every setting with its default and exit",
    )  # fmt: skip
    for name in shown:
        default = getattr(defaults, name)
        text = f"{helps[name]} (default: {default})"
        if isinstance(default, bool):
            p.add_argument(
                flag(name), dest=name, action=argparse.BooleanOptionalAction, default=None,
                help=text,
            )  # fmt: skip
        elif isinstance(default, tuple):
            p.add_argument(flag(name), dest=name, nargs="+", default=None, help=text)
        else:
            kind = type(default)
            p.add_argument(
                flag(name), dest=name, type=kind, default=None, help=text,
                choices=(choices or {}).get(name),
            )  # fmt: skip


def given_settings(args: argparse.Namespace, cls: type, shown: Sequence[str], allowed) -> dict:
    """The settings the command line gives: the file's, then ``--set``'s, then the options'."""
    out: dict[str, Any] = {}
    if getattr(args, "config", None):
        out.update(read_settings(cls, args.config))
    for text in getattr(args, "settings", None) or []:
        key, value = parse_override(cls, text)
        out[key] = value
    for name in shown:
        value = getattr(args, name, None)
        if value is not None:
            out[name] = coerce(cls, name, value, "option ")
    refused = sorted(set(out) - set(allowed))
    if refused:
        raise SettingsError(f"setting {refused[0]!r} is not one of this command's")
    return out


def build_config(make: Callable[..., Any], given: dict, shown: Sequence[str]) -> Any:
    """``make(**given)``; a bad value is a ``ValueError`` naming its setting (as the option
    where it is one)."""
    try:
        return make(**given)
    except ValueError as exc:
        pattern = "|".join(shown)
        text = re.sub(rf"\b({pattern})\b", lambda m: flag(m[1]), str(exc))
        raise ValueError(f"invalid setting: {text}") from None


def resume_command(command: str, args: argparse.Namespace, shown: Sequence[str]) -> str:
    """The command line that continues this run: the same file, overrides and options, plus
    ``--resume``."""
    parts = ["cpp-mujoco", command, "--out", str(args.out), "--resume"]
    parts += ["--paper"] if getattr(args, "paper", False) else []
    parts += ["--config", str(args.config)] if getattr(args, "config", None) else []
    for text in getattr(args, "settings", None) or []:
        parts += ["--set", text]
    for name in shown:
        value = getattr(args, name, None)
        if value is None:
            continue
        if isinstance(value, bool):
            parts.append(flag(name) if value else "--no-" + flag(name)[2:])
        elif isinstance(value, list):
            parts += [flag(name), *map(str, value)]
        else:
            parts += [flag(name), str(value)]
    return shlex.join(parts)
