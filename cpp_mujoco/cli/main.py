"""The ``cpp-mujoco`` command: maps, evaluation, missions, training, the demo and the benchmark.

Bad input is one line on stderr and exit status 2, before anything runs where it can be checked.
Ctrl-C and SIGTERM finalise the files being written (exit 130 / 143) and say which they were.

Every subcommand is registered the same way: an ``add_*(subparsers)`` function adds its parser
and sets ``func``, the command (which returns the exit status, None for 0). The parsers are in
:mod:`cpp_mujoco.cli.parsers`, ``train``'s in :mod:`cpp_mujoco.cli.train`, ``train-general``'s
in :mod:`cpp_mujoco.cli.train_general`. A ``func`` given as ``"module:function"`` is imported by
:func:`command` when it runs — the one place the command line imports lazily — so the commands'
modules import what they use at their top, and ``--help`` and ``--version`` import none of them
(nor torch, MuJoCo, matplotlib).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable

from cpp_mujoco import __version__
from cpp_mujoco.cli.options import TRAIN_GENERAL_HELP, TRAIN_HELP
from cpp_mujoco.cli.parsers import (
    add_benchmark,
    add_demo,
    add_evaluate,
    add_fly,
    add_maps,
    add_optimum,
    add_site,
)
from cpp_mujoco.util.signals import exit_code, interruptible


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (the usage is one ``--help`` away)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


TRAIN_COMMANDS = ("train", "train-general")  # their options need torch


def add_train(sub, options: bool = True) -> None:
    """``train``'s and ``train-general``'s parsers are the agent package's; their options come
    from the training configs, and that package imports torch (seconds), so without ``options``
    only their names and help lines are registered — enough for every other command line."""
    if options:
        from cpp_mujoco.cli.train import add_parser  # heavy: torch (the training configs)
        from cpp_mujoco.cli.train_general import add_parser as add_general_parser  # heavy: torch

        add_parser(sub)
        add_general_parser(sub)
    else:
        sub.add_parser("train", help=TRAIN_HELP)
        sub.add_parser("train-general", help=TRAIN_GENERAL_HELP)


def build_parser(train_options: bool = True) -> argparse.ArgumentParser:
    """The whole command line; ``train_options=False`` leaves out the training commands'
    options (and torch) — :func:`main` does so for every command line without one of them."""
    parser = _Parser(
        prog="cpp-mujoco",
        description="UAV coverage path planning under power constraints, on a grid and in MuJoCo.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    add_maps(sub)
    add_evaluate(sub)
    add_fly(sub)
    add_optimum(sub)
    add_site(sub)
    add_train(sub, options=train_options)
    add_demo(sub)
    add_benchmark(sub)
    return parser


def _interrupted(command: str, exc: KeyboardInterrupt, own_files: bool) -> str:
    """Which files were finalised; everything else this command writes is atomic."""
    why = "SIGTERM" if type(exc).__name__ == "Terminated" else "Ctrl-C"
    text = f"cpp-mujoco {command}: interrupted ({why})"
    finalised = getattr(exc, "files_finalised", {})
    if finalised:
        cut = ", ".join(f"{kind} {path}" for kind, path in finalised.items())
        text += f"; finalised, holding the mission up to the interruption: {cut}"
    if own_files:
        other = "every other file" if finalised else "every file"
        text += f"; {other} it wrote is complete (written atomically)"
    return text


def _input_errors() -> tuple[type[BaseException], ...]:
    """What a command raises for bad input: ValueError (MapError, CheckpointError), OSError
    (WriteError), and RenderingError once the rendering module is loaded — before that nothing
    can have raised it, and importing it only to catch it would slow every command."""
    rendering = sys.modules.get("cpp_mujoco.physics.view.rendering")
    return (ValueError, OSError) + ((rendering.RenderingError,) if rendering else ())


def command(func: str | Callable) -> Callable:
    """A subcommand's ``func``: ``"module:function"`` is imported here, when the command runs
    (the command line's one lazy import: a command's module imports torch, MuJoCo or matplotlib
    at its top); a callable is the command itself."""
    if callable(func):
        return func
    module, _, name = func.partition(":")
    return getattr(importlib.import_module(module), name)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    train_options = any(word in TRAIN_COMMANDS for word in argv)
    args = build_parser(train_options=train_options).parse_args(argv)
    own = not getattr(args, "own_signals", False)  # train saves a checkpoint on its own signals
    try:
        if not own:
            return command(args.func)(args) or 0
        with interruptible():
            code = command(args.func)(args)
    except _input_errors() as e:  # evaluated only when an exception arrives
        message = " ".join(str(e).split("\n")[0].split())
        print(f"cpp-mujoco {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as e:
        print(_interrupted(args.command, e, own), file=sys.stderr)
        return exit_code(e)
    return code or 0


if __name__ == "__main__":
    sys.exit(main())
