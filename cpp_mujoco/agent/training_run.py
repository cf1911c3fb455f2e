"""A training run in its folder: claim the folder (fresh, resumed or replaced on request), train,
release it. Kept apart from the loop (:mod:`~cpp_mujoco.agent.train`) so the rules about folders
(never overwrite unasked, resume from the checkpoint) sit in one short place."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from cpp_mujoco.agent.checkpoint import initial_network
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.network import check_can_start_from
from cpp_mujoco.agent.run_folder import claim_run_folder
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.maps import load_map
from cpp_mujoco.util.io import atomic_write_text
from cpp_mujoco.util.settings import to_toml

T = TypeVar("T", bound=Trainer)


def train(
    config: TrainConfig,
    out_dir: str | os.PathLike,
    *,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool = True,
) -> Trainer:
    """Train (or continue) a run in ``out_dir``, which is locked meanwhile; returns the trainer.

    A non-empty ``out_dir`` needs ``resume`` (continue its checkpoint) or ``overwrite`` (replace
    the run): :class:`~cpp_mujoco.agent.run_folder.RunFolderError` otherwise, before any write.
    """
    start = None
    if config.init_from:  # a bad name or an unfit network fails before the folder is claimed
        start = initial_network(config)
        check_can_start_from(start, *load_map(config.map).shape, config.wind is not None)
    return run_in_folder(
        lambda out: Trainer(config, out, init_network=start), out_dir,
        resume=resume, overwrite=overwrite, progress=progress,
    )  # fmt: skip


def run_in_folder(
    make_trainer: Callable[[Path], T],
    out_dir: str | os.PathLike,
    *,
    resume: bool,
    overwrite: bool,
    progress: bool,
) -> T:
    """Claim ``out_dir``, build the trainer in it, continue its checkpoint if asked, train: the
    folder rules every trainer (per map or general) follows."""
    with claim_run_folder(out_dir, resume=resume, overwrite=overwrite) as out:
        trainer = make_trainer(out)
        if resume and trainer.resume():
            print(f"resuming {out / 'checkpoint.pt'} at update {trainer.updates}")
        elif resume:
            print(f"--resume: no checkpoint.pt in {out}; starting a new run there")
        # the resolved settings, as --config reads them back (after a resume: the run's own)
        atomic_write_text(out / "config.toml", to_toml(trainer.config))
        trainer.run(progress=progress)
    return trainer
