"""``cpp-mujoco train``: the argparse sub-parser (the lead wires ``add_train_parser`` into the CLI).

Every :class:`TrainConfig` field is an option (``--learning-rate``, ``--num-envs`` …), so a run is
reproducible from its command line alone.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

from cpp_mujoco.agent.config import TrainConfig

_HELP = {
    "map": "bundled map name (A, B, C) or PNG path",
    "seed": "random seed (network init, envs, replay sampling, exploration)",
    "device": "torch device: cpu (default) or cuda",
    "total_updates": "training length in gradient updates",
    "max_minutes": "stop after this many minutes of training (0 = no limit)",
    "num_envs": "environments collected in parallel",
    "n_step": "n-step return targets (1 = the paper)",
    "updates_per_step": "gradient updates per vector step",
    "learning_rate": "Adam learning rate",
    "loss": "mse (paper) or huber",
    "threads": "torch CPU threads (0 = all cores)",
}


def add_train_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``train`` sub-command to an ``argparse`` sub-parsers object and return it."""
    p = subparsers.add_parser(
        "train",
        help="train the DDQN agent on a map",
        description="Train the paper's DDQN agent on the grid MDP (defaults: the project's fast CPU"
        " schedule; --paper for the paper's).",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument(
        "--out",
        required=True,
        help="run folder: checkpoint.pt, agent.pt, best.pt, log.csv, training.png",
    )
    p.add_argument(
        "--resume", action="store_true", help="continue the run in --out from its checkpoint.pt"
    )
    p.add_argument(
        "--paper",
        action="store_true",
        help="start from the paper's schedule (1 env, 1-step, MSE, 500k updates)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    defaults = TrainConfig()
    for f in dataclasses.fields(TrainConfig):
        flag = "--" + f.name.replace("_", "-")
        kind = type(getattr(defaults, f.name))
        if kind is bool:
            p.add_argument(flag, dest=f.name, action=argparse.BooleanOptionalAction, default=None)
            continue
        p.add_argument(
            flag,
            dest=f.name,
            type=kind,
            default=None,
            help=_HELP.get(f.name, f.name.replace("_", " "))
            + f" (default {getattr(defaults, f.name)})",
        )
    p.set_defaults(handler=run_train)
    return p


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    given = {
        f.name: getattr(args, f.name)
        for f in dataclasses.fields(TrainConfig)
        if getattr(args, f.name, None) is not None
    }
    return TrainConfig.paper(**given) if getattr(args, "paper", False) else TrainConfig(**given)


def run_train(args: argparse.Namespace) -> int:
    from cpp_mujoco.agent.checkpoint import CheckpointError
    from cpp_mujoco.agent.train import train
    from cpp_mujoco.maps import MapError

    try:
        config = config_from_args(args)
        trainer = train(config, args.out, resume=args.resume, progress=not args.no_progress)
    except (CheckpointError, MapError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    last = trainer.history[-1] if trainer.history else {}
    if last:
        print(
            f"done: {trainer.updates} updates, {trainer.episodes} episodes, {trainer.wall_s:.0f}s; "
            f"landing {last['eval_landing']:.4f}, coverage {last['eval_coverage']:.4f}; "
            f"agent in {args.out}/agent.pt (best: best.pt)"
        )
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="cpp-mujoco")
    add_train_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return args.handler(args)


if __name__ == "__main__":
    raise SystemExit(main())
