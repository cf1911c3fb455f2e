"""A training run's state: everything ``checkpoint.pt`` holds so a run continues exactly.

:class:`TrainingState` is the one definition of that state. The :class:`~cpp_mujoco.agent.train.
Trainer` captures it (:meth:`~cpp_mujoco.agent.train.Trainer.state`) and restores it; this module
turns it into the checkpoint's dict and back (the file layout every earlier run wrote, so their
checkpoints still resume) and says which settings a resumed run may change.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import torch

from cpp_mujoco.agent.checkpoint import TRAIN_KIND, CheckpointError

# settings a resumed run may change: they schedule the run, not what it learns
RESUMABLE_CHANGES = frozenset(
    {"total_updates", "max_minutes", "eval_every", "eval_budget_step", "final_eval",
     "checkpoint_every", "checkpoint_minutes", "device", "threads", "stop_after_updates"}
)  # fmt: skip


@dataclass
class Progress:
    """How far a run is: its counters and the wall time it has trained."""

    updates: int = 0
    env_steps: int = 0
    episodes: int = 0
    wall_s: float = 0.0
    update_credit: float = 0.0  # updates the collected steps earned and not yet made


@dataclass
class TrainingState:
    """Everything a run needs to continue exactly; ``agent`` is the agent file's payload
    (:func:`~cpp_mujoco.agent.checkpoint.agent_payload`: weights, shape, config, rules, map)."""

    agent: dict
    target: dict  # the target network's weights
    optimizer: dict
    replay: dict  # the replay memory's own state_dict
    env: dict  # the vector env's own state_dict, arrays as tensors (weights_only loads)
    obs: dict[str, torch.Tensor]  # the observation the next step acts on
    ep_return: torch.Tensor  # each env's return so far
    rng: dict  # numpy generator (replay sampling, guidance)
    torch_gen: torch.Tensor  # soft-max exploration
    torch_rng: torch.Tensor  # torch's global generator
    progress: Progress
    recent: list[list[float]]  # (return, landed, coverage) of the last training episodes
    history: list[dict]  # one row per evaluation: log.csv
    best: list[float] | None  # best.pt's score

    def to_checkpoint(self) -> dict:
        """The checkpoint's dict: the agent payload's keys plus the rest, ``kind`` a training
        state's."""
        rest = {f.name: getattr(self, f.name) for f in fields(self)}
        del rest["agent"], rest["progress"]
        return {
            **self.agent,
            "kind": TRAIN_KIND,
            **rest,
            "counters": {f.name: getattr(self.progress, f.name) for f in fields(Progress)},
        }

    @classmethod
    def capture(cls, trainer) -> TrainingState:
        """The state of a :class:`~cpp_mujoco.agent.train.Trainer` now."""
        t = trainer
        return cls(
            agent=t.agent_state(),
            target=t.target.state_dict(),
            optimizer=t.optimizer.state_dict(),
            replay=t.replay.state_dict(),
            env=env_state(t.env.unwrapped),
            obs={k: torch.from_numpy(np.array(v)) for k, v in t.obs.items()},
            ep_return=torch.from_numpy(t.ep_return.copy()),
            rng=t.rng.bit_generator.state,
            torch_gen=t.torch_gen.get_state(),
            torch_rng=torch.get_rng_state(),
            progress=Progress(t.updates, t.env_steps, t.episodes, t.wall_s, t.update_credit),
            recent=[list(map(float, r)) for r in t.recent],
            history=t.history,
            best=list(t.best) if t.best else None,
        )

    def restore_into(self, trainer) -> None:
        """Put this state into a trainer of the same run (networks built, env made)."""
        t = trainer
        t.online.load_state_dict(self.agent["network"])
        t.target.load_state_dict(self.target)
        t.optimizer.load_state_dict(self.optimizer)
        if t.fused_adam:  # a checkpoint's groups carry their own flags
            for group in t.optimizer.param_groups:
                group["fused"], group["foreach"] = True, None
                for p in group["params"]:  # the fused step keeps its count beside the parameter
                    st = t.optimizer.state.get(p, {})
                    if "step" in st:
                        step = st["step"]
                        st["step"] = torch.as_tensor(step, dtype=torch.float32, device=p.device)
        t.replay.load_state_dict(self.replay)
        venv = t.env.unwrapped
        load_env_state(venv, self.env)
        t.obs = {k: v.numpy().copy() for k, v in self.obs.items()}
        if hasattr(venv, "mdp"):  # the grid env's map: a read-only view of its one map again
            t.obs["map"] = venv.mdp.observation()["map"]
        t.ep_return = self.ep_return.numpy().copy()
        t.rng.bit_generator.state = self.rng
        t.torch_gen.set_state(self.torch_gen)
        torch.set_rng_state(self.torch_rng)
        p = self.progress
        t.updates, t.env_steps, t.episodes = p.updates, p.env_steps, p.episodes
        t.wall_s, t.update_credit = p.wall_s, p.update_credit
        t.recent.extend(tuple(r) for r in self.recent)
        t.history = list(self.history)
        t.best = tuple(self.best) if self.best else None

    @classmethod
    def from_checkpoint(cls, obj: dict) -> TrainingState:
        """The state a (validated) checkpoint holds; :class:`CheckpointError` for an agent file
        or one that lacks part of the state."""
        if obj.get("kind") != TRAIN_KIND:
            raise CheckpointError(
                "an agent file cannot be resumed; pass a training checkpoint (checkpoint.pt)"
            )
        own = [f.name for f in fields(cls) if f.name not in ("agent", "progress")]
        missing = [k for k in (*own, "counters") if k not in obj]
        if missing:
            raise CheckpointError(f"the training checkpoint lacks {', '.join(missing)}")
        try:
            progress = Progress(**obj["counters"])
        except TypeError as exc:
            raise CheckpointError(f"the checkpoint's counters are not a run's ({exc})") from None
        agent = {k: v for k, v in obj.items() if k not in (*own, "counters")}
        return cls(agent=agent, progress=progress, **{k: obj[k] for k in own})


def env_state(venv) -> dict:
    """A vector env's ``state_dict``, its arrays as tensors."""
    return {
        k: torch.from_numpy(v) if isinstance(v, np.ndarray) else v
        for k, v in venv.state_dict().items()
    }


def load_env_state(venv, state: dict) -> None:
    """The inverse of :func:`env_state`; :class:`CheckpointError` for a state of another env."""
    try:
        venv.load_state_dict(
            {k: v.numpy() if isinstance(v, torch.Tensor) else v for k, v in state.items()}
        )
    except ValueError as exc:
        raise CheckpointError(
            f"the checkpoint's environment state does not fit this run ({exc}); "
            "it was written by another version"
        ) from None


def changed_settings(stored: dict, given: dict, resumable: frozenset[str]) -> list[str]:
    """The learning settings in which ``given`` differs from the run's ``stored`` ones."""
    return [
        f"{k} {stored[k]!r} (stored) vs {given[k]!r} (given)"
        for k in given
        if k not in resumable and given[k] != stored.get(k)
    ]
