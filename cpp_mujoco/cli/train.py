"""``cpp-mujoco train``: its sub-parser, registered like every subcommand (:func:`add_parser`
sets ``func``; :mod:`cpp_mujoco.cli.main` assembles the command line).

The settings a person changes run by run are options (``--map``, ``--total-updates`` …); every
other :class:`TrainConfig` field comes from ``--config FILE`` (TOML) or ``--set KEY=VALUE``
(:mod:`cpp_mujoco.cli.settings_options`), and the run folder keeps the resolved settings
(``config.toml``). Exit codes: 0 done, 2 bad input (one line on stderr, nothing written),
130/143 stopped by SIGINT/SIGTERM after saving a resumable checkpoint.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

from cpp_mujoco.agent.checkpoint import CheckpointError
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.run_folder import TrainingInterrupted
from cpp_mujoco.agent.training_run import train
from cpp_mujoco.cli.settings_options import (
    add_settings_options,
    build_config,
    given_settings,
)
from cpp_mujoco.cli.settings_options import resume_command as settings_resume_command
from cpp_mujoco.maps import MapError

# one sentence per TrainConfig field (tests/test_agent_train.py checks that none is missing)
_HELP = {
    "map": "bundled map name (A, B, C) or the path of a PNG map",
    "seed": "random seed for network init, environments, replay sampling and exploration",
    "min_budget": "smallest movement budget drawn for a training episode",
    "max_budget": "largest movement budget drawn for a training episode",
    "gamma": "discount factor of future rewards",
    "tau": "soft target-network update rate per gradient update; the paper's is 0.005",
    "buffer_size": "replay memory size in transitions",
    "batch_size": "minibatch size of each gradient update",
    "beta": "soft-max exploration temperature: π(a|s) ∝ exp(Q(s,a)/β)",
    "learning_rate": "Adam learning rate (peak, after warm-up)",
    "lr_warmup_updates": "updates of linear learning-rate warm-up from 0 (0 = none)",
    "lr_final": "learning rate at the end of the cosine decay, as a fraction (1 = constant)",
    "adam_eps": "Adam's epsilon, added to the gradient scale for numerical stability",
    "loss": "TD loss: mse (the paper) or huber (robust to the −150 crash reward)",
    "max_grad_norm": "clip the gradient norm to this (0 = no clipping)",
    "num_envs": "environments stepped together, one batched forward pass per step",
    "n_step": "n-step return targets (1 = the paper)",
    "updates_per_step": "gradient updates per vector step of num-envs environment steps",
    "wind_max_speed": "train in the grid's wind option, winds up to this m/s (0 = the paper)",
    "wind_calm_fraction": "share of calm-air training episodes with the wind option",
    "wind_gust_scale": "wind option: each episode's gust spread × a factor uniform in 1..this",
    "crash_reward": "the MDP's crash reward while training (the paper's: −150); evaluation"
    " reports landing and coverage, which do not depend on it",
    "move_reward": "the MDP's reward per move while training (the paper's: −0.2; 0 with gamma"
    " near 1: coverage is the objective); evaluation reports landing and coverage",
    "init_from": "start from this agent's weights (bundled name or file; empty = random)",
    "stop_after_updates": "end the run at this many updates, keeping the schedules of"
    " --total-updates (0 = at --total-updates): a staged run's first stage",
    "return_mask": "act only among the actions after which the way home is still paid (the safe"
    " greedy planner's return rule): every calm grid episode lands; off = the paper's agent",
    "backend": "where the training episodes are flown: grid (the MDP) or mujoco (fine-tuning in"
    " physics, several weathers at once; the evaluation stays on the grid)",
    "physics_wind_speed": "backend mujoco: steady wind of the windy slots, m/s (0 = all calm)",
    "physics_wind_directions": "backend mujoco: where that wind blows from, letters of NESW, one"
    " group of slots each",
    "physics_turbulence": "backend mujoco: Dryden turbulence of the windy slots (none, light,"
    " moderate, severe)",
    "physics_calm_share": "backend mujoco: share of the slots in calm, still air",
    "physics_threads": "backend mujoco: threads stepping MuJoCo in each weather's slots",
    "guide": "reference planner that drives the guided environments",
    "guide_fraction": "fraction of environments the guide drives at the start (0 = the paper)",
    "guide_epsilon": "probability that a guided environment takes the agent's own action",
    "guide_updates": "updates over which guidance decays linearly to none",
    "demo_planner": "planner that flies the demonstrations (every landing cell × budget)",
    "demo_fraction": "fraction of each minibatch drawn from demonstrations (0 = the paper)",
    "demo_margin": "large-margin loss margin on demonstrations, in reward units",
    "demo_weight": "weight of the large-margin loss",
    "wind_planner_sigmas": "margin the wind planners keep as guide or demonstrator: standard"
    " deviations of the way home's spread in gusty wind",
    "learning_starts": "environment steps collected before the first update",
    "total_updates": "training length in gradient updates",
    "max_minutes": "stop after this many minutes of training (0 = no limit)",
    "eval_every": "greedy evaluation (logged, plotted, best.pt) every so many updates",
    "eval_budget_step": "evaluate on every n-th budget (1 = the full protocol)",
    "final_eval": "run the full protocol on the final agent and write final_eval.json",
    "best_by": "best.pt keeps the evaluation with the highest return or the most landings",
    "checkpoint_every": "save a resumable checkpoint.pt every so many updates",
    "checkpoint_minutes": "also save one every so many minutes of wall time (0 = off)",
    "budget_scale": "network input = budget / this (0 = max-budget)",
    "device": "torch device: cpu or cuda",
    "threads": "torch CPU threads (0 = pick the faster of 1 and all cores while training)",
}

# fine-tuning a wind agent in physics: its own wind option (it observes the wind; the grid
# evaluation flies it), calm air and 9 m/s moderate turbulence from N, E, S and W in MuJoCo
FINETUNE_EXAMPLE = (
    "cpp-mujoco train --map B --backend mujoco --init-from B-wind --wind-max-speed 12"
    " --set wind_calm_fraction=0.35 --set physics_wind_speed=9 --set physics_calm_share=0.2"
    " --set guide_fraction=0 --set demo_fraction=0 --learning-rate 1e-4 --total-updates 3000"
    " --set best_by=landing --out runs/finetune-B"
)
# the settings shown as options; the others: --config FILE, --set KEY=VALUE, --list-settings
SHOWN = (
    "map", "seed", "total_updates", "max_minutes", "stop_after_updates", "eval_every",
    "learning_rate", "num_envs", "return_mask", "wind_max_speed", "backend", "init_from",
    "threads",
)  # fmt: skip
ALLOWED = tuple(f.name for f in dataclasses.fields(TrainConfig))


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``train`` sub-command to an ``argparse`` sub-parsers object and return it.

    ``own_signals``: training turns SIGINT/SIGTERM into a saved checkpoint itself, so the
    command line leaves its signals alone."""
    p = subparsers.add_parser(
        "train",
        help="train the DDQN agent on a map",
        description="Train the paper's DDQN agent on the grid MDP (defaults: the project's fast CPU"
        " schedule; --paper for the paper's), or fine-tune one in MuJoCo (--backend mujoco)."
        " SIGINT/SIGTERM save a resumable checkpoint.",
        epilog=f"fine-tune the bundled wind agent of map B in physics: {FINETUNE_EXAMPLE}",
    )
    p.add_argument(
        "--out",
        required=True,
        help="run folder: checkpoint.pt, agent.pt, best.pt, log.csv, training.png",
    )
    folder = p.add_mutually_exclusive_group()
    folder.add_argument(
        "--resume", action="store_true", help="continue the run in --out from its checkpoint.pt"
    )
    folder.add_argument(
        "--overwrite", action="store_true", help="replace the run in a non-empty --out"
    )
    p.add_argument(
        "--paper",
        action="store_true",
        help="start from the paper's schedule (1 env, 1-step, MSE, 500k updates)",
    )
    p.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar (there is none anyway when stderr is not a terminal)",
    )
    add_settings_options(p, TrainConfig, SHOWN, _HELP, ALLOWED)
    p.set_defaults(func=run_train, own_signals=True)
    return p


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """The config the command line describes; a bad value is a ``ValueError`` naming it."""
    given = given_settings(args, TrainConfig, SHOWN, ALLOWED)
    make = TrainConfig.paper if getattr(args, "paper", False) else TrainConfig
    return build_config(make, given, SHOWN)


def resume_command(args: argparse.Namespace) -> str:
    """The command line that continues this run (same settings, plus ``--resume``)."""
    return settings_resume_command("train", args, SHOWN)


def run_train(args: argparse.Namespace) -> int:
    return run_training(args, "train", config_from_args, resume_command(args))


def run_training(args: argparse.Namespace, command: str, make_config, resume: str) -> int:
    """Train the run the command line describes (``make_config(args)``), one per-map or general;
    ``resume``: the command line that continues it after a signal."""
    progress = not args.no_progress and sys.stderr.isatty()
    try:
        config = make_config(args)
        trainer = train(
            config, args.out, resume=args.resume, overwrite=args.overwrite, progress=progress
        )
    except TrainingInterrupted as stop:
        print(
            f"cpp-mujoco {command}: {stop} (agent: {stop.checkpoint.parent / 'agent.pt'})\n"
            f"continue with: {resume}",
            file=sys.stderr,
        )
        return 128 + stop.signum
    except (CheckpointError, MapError, ValueError, OSError) as exc:  # OSError: WriteError too
        print(f"cpp-mujoco {command}: error: {exc}", file=sys.stderr)
        return 2
    last = trainer.history[-1] if trainer.history else {}
    where = f"agent in {args.out}/agent.pt (best evaluated: best.pt)"
    if last:
        print(
            f"done: {trainer.updates} updates, {trainer.episodes} episodes, {trainer.wall_s:.0f}s;"
            f" {trainer.maps.judged_on} landing {last['eval_landing']:.4f}, coverage "
            f"{last['eval_coverage']:.4f}; {where}"
        )
    else:
        print(f"done: {trainer.updates} updates; {where}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="cpp-mujoco")
    add_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    raise SystemExit(main())
