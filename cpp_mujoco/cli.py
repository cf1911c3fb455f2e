"""The ``cpp-mujoco`` command: maps, evaluation, missions, training, the demo and the benchmark.

Bad input is one line on stderr and exit status 2, before anything runs where it can be checked.
Ctrl-C and SIGTERM finalise the files being written (exit 130 / 143) and say which they were.

Every subcommand is registered the same way: an ``add_*(subparsers)`` function adds its parser
and sets ``func`` (which returns the exit status, None for 0) — ``maps``, ``evaluate``, ``fly``
and ``demo`` in :mod:`cpp_mujoco.commands`, ``train`` in :mod:`cpp_mujoco.agent.cli`,
``train-general`` in :mod:`cpp_mujoco.agent.general_cli`,
``benchmark`` in :mod:`cpp_mujoco.benchmark`. Heavy modules (torch, MuJoCo, matplotlib) are
imported inside the commands, so ``--help`` and ``--version`` answer at once.
"""

from __future__ import annotations

import argparse
import sys

from cpp_mujoco import __version__
from cpp_mujoco.benchmark import add_parser as add_benchmark
from cpp_mujoco.commands import add_demo, add_evaluate, add_fly, add_maps
from cpp_mujoco.optimum_commands import add_optimum


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (the usage is one ``--help`` away)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


TRAIN_HELP = "train the DDQN agent on a map"
TRAIN_GENERAL_HELP = "train one DDQN agent for any map on generated maps"
TRAIN_COMMANDS = ("train", "train-general")  # their options need torch


def add_train(sub, options: bool = True) -> None:
    """``train``'s and ``train-general``'s parsers are the agent package's; their options come
    from the training configs, and that package imports torch (seconds), so without ``options``
    only their names and help lines are registered — enough for every other command line."""
    if options:
        from cpp_mujoco.agent.cli import add_parser
        from cpp_mujoco.agent.general_cli import add_parser as add_general_parser

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
    rendering = sys.modules.get("cpp_mujoco.review.rendering")
    return (ValueError, OSError) + ((rendering.RenderingError,) if rendering else ())


def main(argv: list[str] | None = None) -> int:
    from cpp_mujoco.signals import exit_code, interruptible

    argv = sys.argv[1:] if argv is None else list(argv)
    train_options = any(word in TRAIN_COMMANDS for word in argv)
    args = build_parser(train_options=train_options).parse_args(argv)
    own = not getattr(args, "own_signals", False)  # train saves a checkpoint on its own signals
    try:
        if not own:
            return args.func(args) or 0
        with interruptible():
            code = args.func(args)
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
