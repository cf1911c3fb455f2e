"""``cpp-mujoco train-general``: one agent for maps it has never seen, trained on generated maps.

Registered like ``train`` (:mod:`cpp_mujoco.cli.train`): the settings changed run by run are
options, every other :class:`GeneralTrainConfig` field comes from ``--config FILE`` or
``--set KEY=VALUE`` (the learning settings with ``train``'s help text); the fields the general
run does not use (the map, budgets, the physics fine-tuning) are refused; the grid's wind option
(``--wind-max-speed``) is one, with the return mask priced at the observed wind. Exit codes as
``train``'s: 0 done, 2 bad input, 130/143 stopped by a signal after saving a checkpoint.
"""

from __future__ import annotations

import argparse
import dataclasses

from cpp_mujoco.agent.general_config import ARCHITECTURES, UNUSED, GeneralTrainConfig
from cpp_mujoco.cli.options import TRAIN_GENERAL_HELP as HELP  # the light parser's line: the same
from cpp_mujoco.cli.settings_options import (
    add_settings_options,
    build_config,
    given_settings,
)
from cpp_mujoco.cli.settings_options import resume_command as settings_resume_command
from cpp_mujoco.cli.train import _HELP, run_training

COMMAND = "train-general"
# the per-map trainer's physics fine-tuning is not the general agent's (its grid wind option is)
PHYSICS = ("backend", "physics_wind_speed", "physics_wind_directions", "physics_turbulence",
           "physics_calm_share", "physics_threads")  # fmt: skip
EXCLUDED = (*UNUSED, *PHYSICS)
_GENERAL_HELP = {
    "sizes": "map sides trained together, each flown with its size class's budgets",
    "maps_per_size": "generated training maps of each size (seeds map-seed on)",
    "map_seed": "first training map seed (training seeds stay below 1,000,000)",
    "episodes_per_map": "episodes an environment flies on a map before it draws another",
    "door_walls": "chance a generated training map has a wall across it with one door (as on "
    "map C; the generator's door_wall)",
    "map_family": "the generator's family of the training and validation maps: paper (the "
    "paper-style maps), city (streets, buildings and low obstacles that hide what lies behind "
    "them; needs obstacle_input=true), scatter (small blocks, a tiny landing pad), field (open "
    "ground, target patches), or several joined by + (paper+scatter+field+city), taken in turn",
    "named_maps": "maps trained beside the generated ones: bundled names or PNG paths (the "
    "paper's A B C, your site); each flies its size class's budgets, with demonstrations",
    "named_share": "fraction of the training episodes flown on the --named-maps",
    "val_maps_per_size": "validation maps of each size, on which best.pt is chosen",
    "val_seed": "first validation map seed (2,000,000..2,999,999)",
    "demo_maps_per_size": "training maps of each size the demo planner flies (the first ones)",
    "demo_max_side": "the demo planner flies only maps of sides up to this (0 = all; the wind "
    "planners take minutes a 32x32 map)",
    "demo_budget_step": "demonstrations fly every n-th budget of each size class",
    "named_demo_budget_step": "the --named-maps' demonstrations fly every n-th budget "
    "(0 = --demo-budget-step; 1 = every budget of the protocol)",
    "named_demo_share": "fraction of each demonstration minibatch drawn from the --named-maps "
    "(0 = uniform over all recorded transitions)",
    "final_budget_step": "the final evaluation's budget step (1 = the full protocol)",
    "architecture": "the network: global-local (Theile et al. 2021: a crop and a pooled view "
    "of the map centred on the UAV) or fcn (fully convolutional, global max/mean pooling and "
    "the UAV's cell; reads neither --local-size nor --global-size)",
    "local_size": "side of the full-resolution view around the UAV (odd)",
    "global_size": "side the whole centred map is average-pooled to",
    "conv_filters": "filters of each convolution (fcn: of the half-resolution layers)",
    "hidden": "units of each dense layer",
    "num_hidden": "dense layers before the Q-values",
    "max_side": "largest map side: the global-local network's canvas holds it, the fcn's "
    "receptive field covers it (0 = the largest of --sizes)",
    "home_input": "the network also reads the moves home (fewest moves from the UAV's cell to "
    "a landing cell, / the budget scale); --resume keeps the run's own setting (off for runs "
    "from before the option)",
    "return_mask": "act only among the actions after which the way home is still paid (the "
    "safe greedy planner's return rule), in training and as a policy; --resume keeps the run's "
    "own setting (off for runs from before the option)",
    "revisit_mask": "as a policy (validation, the agent file), also leave out the moves back "
    "into a cell flown through since the coverage last grew that shows no unseen target (not "
    "in training's exploration; off for agents from before the option)",
    "target_input": "the network also reads, for each action, the moves from the cell it leads "
    "to until the 3x3 view holds an unseen target (global-local only; from an --init-from "
    "network without it, the new inputs start at zero weight)",
    "obstacle_input": "the network also reads the map's obstacle layer as one more grid channel "
    "(either architecture; without it an agent refuses maps with obstacles; from an --init-from "
    "network without it, the channel starts at zero weight)",
    "named_symmetries": "also train on every --named-maps map's rotations and mirror images "
    "(8 for a square map), not only its own orientation",
    "finish_mask": "as a policy (validation, the agent file), do not land while a cell showing "
    "an unseen target can be reached and left for home (not in training; off for agents from "
    "before the option)",
    "symmetric_q": "as a policy (validation, the agent file), take the argmax of the Q-values "
    "averaged over the map's rotations and mirror images (8 network readings a step)",
    "init_from": "start from this general agent's weights (a run's agent.pt or best.pt of the "
    "same network; empty = random)",
    "eval_budget_step": "validation flies every n-th budget of each size class",
    "budget_scale": "network input = budget / this (0 = the largest budget of --sizes)",
}


ALLOWED = tuple(f.name for f in dataclasses.fields(GeneralTrainConfig) if f.name not in EXCLUDED)
# the settings shown as options; the others: --config FILE, --set KEY=VALUE, --list-settings
SHOWN = (
    "seed", "sizes", "maps_per_size", "total_updates", "max_minutes", "stop_after_updates",
    "eval_every", "learning_rate", "num_envs", "return_mask", "architecture", "target_input",
    "named_maps", "wind_max_speed", "init_from", "threads",
)  # fmt: skip
HELPS = {name: _GENERAL_HELP.get(name) or _HELP[name] for name in ALLOWED}


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        COMMAND,
        help=HELP,
        description="Train one size-independent DDQN agent (Theile et al. 2021's global-local "
        "network, or a fully convolutional one: --architecture fcn) on generated 16x16 and "
        "32x32 maps, validated on maps of other seeds. "
        "SIGINT/SIGTERM save a resumable checkpoint.",
    )
    p.add_argument(
        "--out", required=True, help="run folder: checkpoint.pt, agent.pt, best.pt, log.csv …"
    )
    folder = p.add_mutually_exclusive_group()
    folder.add_argument("--resume", action="store_true", help="continue the run in --out")
    folder.add_argument("--overwrite", action="store_true", help="replace the run in --out")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_settings_options(
        p, GeneralTrainConfig, SHOWN, HELPS, ALLOWED, choices={"architecture": ARCHITECTURES}
    )
    p.set_defaults(func=run_train_general, own_signals=True)
    return p


def config_from_args(args: argparse.Namespace) -> GeneralTrainConfig:
    """The config the command line describes; a bad value is a ``ValueError`` naming it."""
    given = given_settings(args, GeneralTrainConfig, SHOWN, ALLOWED)
    return build_config(GeneralTrainConfig, given, SHOWN)


def resume_command(args: argparse.Namespace) -> str:
    """The command line that continues this run (same settings, plus ``--resume``)."""
    return settings_resume_command(COMMAND, args, SHOWN)


def run_train_general(args: argparse.Namespace) -> int:
    return run_training(args, COMMAND, config_from_args, resume_command(args))
