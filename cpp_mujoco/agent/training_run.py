"""A training run in its folder: claim the folder (fresh, resumed or replaced on request), train,
release it. Kept apart from the loop (:mod:`~cpp_mujoco.agent.train`) so the rules about folders
(never overwrite unasked, resume from the checkpoint) sit in one short place."""

from __future__ import annotations

import os

from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_training import initial_general_weights, training_pool
from cpp_mujoco.agent.map_training import starting_network
from cpp_mujoco.agent.run_folder import claim_run_folder
from cpp_mujoco.agent.train import Trainer, build_parts
from cpp_mujoco.util.io import atomic_write_text
from cpp_mujoco.util.settings import to_toml


def starting_weights(config: TrainConfig):
    """The starting weights ``init_from`` names, loaded and checked against the run (None without
    one); a general run's named maps are checked too. What can fail before a folder is claimed
    (``CheckpointError``, ``MapError``, ``ValueError``)."""
    if isinstance(config, GeneralTrainConfig):
        weights = initial_general_weights(config)
        training_pool(config, per_size=1)
        return weights
    return starting_network(config)


def train(
    config: TrainConfig,
    out_dir: str | os.PathLike,
    *,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool = True,
) -> Trainer:
    """Train (or continue) a run in ``out_dir``, which is locked meanwhile; returns the trainer.
    A per-map run for a :class:`TrainConfig`, the general agent's for a
    :class:`GeneralTrainConfig` (:func:`~cpp_mujoco.agent.train.build_parts`).

    A non-empty ``out_dir`` needs ``resume`` (continue its checkpoint) or ``overwrite`` (replace
    the run): :class:`~cpp_mujoco.agent.run_folder.RunFolderError` otherwise, before any write.
    """
    init = starting_weights(config)  # a bad file or map fails before the folder is claimed
    with claim_run_folder(out_dir, resume=resume, overwrite=overwrite) as out:
        trainer = Trainer(config, out, build_parts(config, init))
        if resume and trainer.resume():
            print(f"resuming {out / 'checkpoint.pt'} at update {trainer.updates}")
        elif resume:
            print(f"--resume: no checkpoint.pt in {out}; starting a new run there")
        # the resolved settings, as --config reads them back (after a resume: the run's own)
        atomic_write_text(out / "config.toml", to_toml(trainer.config))
        trainer.run(progress=progress)
    return trainer
