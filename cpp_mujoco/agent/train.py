"""The training loop, one for every agent: batched collection, DDQN updates, periodic greedy
evaluation, checkpoints.

A run is built from parts (:class:`~cpp_mujoco.agent.training_parts.TrainingParts`: a map source,
an env, a replay memory, a network, a guide, demonstrations): a per-map run's
(:func:`~cpp_mujoco.agent.map_training.map_parts`) or the general agent's
(:func:`~cpp_mujoco.agent.general_training.general_parts`); :func:`build_parts` picks by the
config's type. One iteration = one vector step of ``num_envs`` environments (actions from one
batched forward pass, sampled from the soft-max policy) followed by ``updates_per_step`` gradient
updates. Every ``eval_every`` updates the greedy policy flies the map source's protocol, logged to
``log.csv`` and ``training.png`` (the paper's Fig. 4). ``checkpoint.pt`` (resumable: a
:class:`~cpp_mujoco.agent.training_state.TrainingState`) and ``agent.pt`` are written atomically
every ``checkpoint_every`` updates, every ``checkpoint_minutes`` and when SIGINT/SIGTERM stops the
run; ``best.pt`` keeps the best evaluated agent. A per-map run with ``backend="mujoco"`` fine-tunes
in physics; a resume ends the episodes in flight there at their last stored step (MuJoCo's state
is not saved) and starts fresh ones.
"""

from __future__ import annotations

import os
import time
from collections import deque
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from cpp_mujoco.agent.checkpoint import agent_payload, atomic_save
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.ddqn import ddqn_update, mask_unsafe, softmax_actions
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_training import general_parts
from cpp_mujoco.agent.home_input import safe_actions
from cpp_mujoco.agent.map_training import map_parts
from cpp_mujoco.agent.network import observation_to_tensors, scalar_inputs
from cpp_mujoco.agent.policy import GreedyAgent
from cpp_mujoco.agent.replay import concatenate_batches
from cpp_mujoco.agent.rules import make_rules
from cpp_mujoco.agent.run_folder import StopSignals, TrainingInterrupted
from cpp_mujoco.agent.threads import ThreadTuner, set_threads
from cpp_mujoco.agent.training_parts import TrainingParts
from cpp_mujoco.agent.training_plot import write_training_log
from cpp_mujoco.agent.training_state import TrainingState


def build_parts(config: TrainConfig, init=None) -> TrainingParts:
    """A run's parts by its config: the general agent's for a :class:`GeneralTrainConfig`, a
    per-map run's otherwise; ``init``: the starting weights if already loaded (else each loads
    its own, ``init_from``)."""
    if isinstance(config, GeneralTrainConfig):
        return general_parts(config, init)
    return map_parts(config, init)


class Trainer:
    def __init__(
        self,
        config: TrainConfig,
        out_dir: str | os.PathLike,
        parts: TrainingParts | None = None,
    ):
        """``parts``: what the run trains on and with (default: :func:`build_parts`)."""
        self.config = c = config
        self.out = Path(out_dir)
        self.device = torch.device(c.device)
        set_threads(c.threads)
        cores = os.cpu_count() or 1
        self.tuner = ThreadTuner((1, cores)) if c.threads == 0 and cores > 1 else None
        self.parts = parts = parts if parts is not None else build_parts(c)
        self.maps, self.env, self.replay = parts.maps, parts.env, parts.replay
        self.guide, self.demos = parts.guide, parts.demos
        torch.manual_seed(c.seed)
        self._build_networks()
        self.rng = np.random.default_rng(c.seed)
        self.torch_gen = torch.Generator().manual_seed(c.seed)
        self.obs, _ = self.env.reset(seed=c.seed)
        self.updates = self.env_steps = self.episodes = 0
        self.wall_s = 0.0
        self.update_credit = 0.0
        self.ep_return = np.zeros(c.num_envs)
        self.recent = deque(maxlen=200)  # (return, landed, coverage) of finished training episodes
        self.history: list[dict] = []
        self.best: tuple[float, float] | None = None
        self.last_stats = {"loss": float("nan"), "q": float("nan")}
        self.last_eval: tuple[int, int, object] | None = None  # (updates, budget step, result)
        self.last_save = time.perf_counter()  # for checkpoint_minutes

    def _build_networks(self) -> None:
        """The online and target networks of the config, and their optimiser."""
        c, fused = self.config, self.fused_adam
        self.online = self.parts.network(c).to(self.device)
        self.target = self.parts.network(c).to(self.device)
        self.target.load_state_dict(self.online.state_dict())
        options = {"fused": fused} if fused else {}
        self.optimizer = torch.optim.Adam(
            self.online.parameters(), lr=c.learning_rate, eps=c.adam_eps, **options
        )

    @property
    def fused_adam(self) -> bool:
        """Adam's fused step where the parts ask for it and torch has one: the same update,
        measured 0.9 ms instead of 8 ms per step on the CPU (the per-tensor loop's Python)."""
        return self.parts.fused_adam and self.device.type in ("cpu", "cuda")

    # ------------------------------------------------------------------ collection and learning
    def collect(self) -> None:
        c, net = self.config, self.online
        grid, scalars = observation_to_tensors(
            self.obs, c.input_budget_scale, self.device, net.wind_inputs, net.home_input,
            net.obstacle_input,
        )  # fmt: skip
        with torch.no_grad():
            q = self.online(grid, scalars).cpu()
        if c.return_mask:  # the soft-max samples among the actions that keep the way home paid
            o = self.obs
            safe = safe_actions(o["map"], o["position"], o["budget"], o["wind"], c.wind_margin)
            q = mask_unsafe(q, torch.from_numpy(safe))
        actions = softmax_actions(q, c.beta, self.torch_gen).numpy()
        guided = self.guided_envs()
        if guided:
            sub = {k: np.asarray(v)[:guided] for k, v in self.obs.items()}
            plan = np.asarray(self.guide.act(sub), dtype=np.int64)
            own = self.rng.random(guided) < c.guide_epsilon  # keep some of the agent's actions
            actions[:guided] = np.where(own, actions[:guided], plan)
        next_obs, reward, terminated, truncated, info = self.env.step(actions)
        self.replay.add(self.obs, actions, reward, terminated)
        self.obs = next_obs
        self.env_steps += c.num_envs
        self.ep_return += reward
        if terminated.any():
            final = info["final_info"]
            for i in np.flatnonzero(terminated[guided:]) + guided:  # the agent's own episodes
                self.recent.append(
                    (self.ep_return[i], bool(final["landed"][i]), float(final["coverage_ratio"][i]))
                )
            self.ep_return[terminated] = 0.0
            self.episodes += int(terminated.sum())

    def guided_envs(self) -> int:
        """How many of the envs (the first ones) the guide drives now: ``guide_fraction`` of them,
        decaying linearly to none at ``guide_updates``."""
        c = self.config
        if c.guide_fraction <= 0 or c.guide_updates <= 0:
            return 0
        left = max(0.0, 1.0 - self.updates / c.guide_updates)
        return int(round(c.guide_fraction * left * c.num_envs))

    def batch(self) -> dict[str, torch.Tensor]:
        """A minibatch of the agent's own transitions, with ``demo_fraction`` of it drawn from the
        demonstrations (marked by ``demo``)."""
        c = self.config
        n_demo = int(round(c.demo_fraction * c.batch_size)) if self.demos else 0
        s = self.replay.sample(c.batch_size - n_demo, self.rng)
        demo = np.zeros(c.batch_size, dtype=bool)
        if n_demo:
            s = concatenate_batches(s, self.demos.sample(n_demo, self.rng))
            demo[-n_demo:] = True
        d = self.device
        scale, wind = c.input_budget_scale, self.online.wind_inputs
        (g, b, wd, h), (ng, nb, nwd, nh) = s["obs"], s["next_obs"]
        if not self.online.home_input:
            h = nh = None
        masked = {"next_safe": torch.from_numpy(s["next_safe"]).to(d)} if c.return_mask else {}
        return {  # "budget" holds the network's scalar inputs: the budget (, wind, moves home)
            "grid": torch.from_numpy(g).to(d),
            "budget": torch.from_numpy(scalar_inputs(b, wd, scale, wind, h)).to(d),
            "action": torch.from_numpy(s["action"]).to(d),
            "return": torch.from_numpy(s["return"]).to(d),
            "next_grid": torch.from_numpy(ng).to(d),
            "next_budget": torch.from_numpy(scalar_inputs(nb, nwd, scale, wind, nh)).to(d),
            "discount": torch.from_numpy(s["discount"]).to(d),
            "demo": torch.from_numpy(demo).to(d),
            **masked,
        }

    def learning_rate(self) -> float:
        return self.config.learning_rate_at(self.updates)

    def update(self) -> None:
        c = self.config
        for group in self.optimizer.param_groups:
            group["lr"] = self.learning_rate()
        if self.tuner:
            self.tuner.before(self.updates)
            t0 = time.perf_counter()
        self.last_stats = ddqn_update(
            self.online,
            self.target,
            self.optimizer,
            self.batch(),
            tau=c.tau,
            loss_kind=c.loss,
            max_grad_norm=c.max_grad_norm,
            margin=c.demo_margin,
            margin_weight=c.demo_weight,
        )
        if self.tuner:
            self.tuner.after(self.updates, time.perf_counter() - t0)
        self.updates += 1

    # ------------------------------------------------------------------ evaluation and logging
    def agent(self) -> GreedyAgent:
        """The greedy agent of the online network, acting with the run's rules."""
        c = self.config
        return GreedyAgent(
            self.online, c.input_budget_scale, self.device, name=self.maps.agent_name,
            rules=make_rules(c.rule_names(), c.wind_margin),
        )  # fmt: skip

    def evaluate(self, full: bool = False):
        """The greedy agent on the map source's protocol, every ``eval_budget_step``-th budget
        (``full``: the final evaluation's budgets, with what the source shows beside it)."""
        step = self.maps.budget_step(full)
        if self.last_eval is not None and self.last_eval[:2] == (self.updates, step):
            res = self.last_eval[2]  # these weights were just evaluated on these budgets
        else:
            res = self.maps.evaluate(self.agent(), step)
            self.online.train()
            self.last_eval = (self.updates, step, res)
        if full:
            self.maps.complete(res, step)
        return res

    def log(self, res) -> dict:
        """Add an evaluation to the history; rewrite ``log.csv`` and ``training.png``."""
        now, (t_mark, updates, steps) = time.perf_counter(), self._mark
        recent = np.array(self.recent, dtype=float) if self.recent else np.full((1, 3), np.nan)
        row = {
            "updates": self.updates, "env_steps": self.env_steps, "episodes": self.episodes,
            "wall_s": round(self.wall_s, 1), "eval_landing": res.landing_ratio,
            "eval_coverage": res.coverage_ratio, "eval_return": float(res.returns.mean()),
            "train_return": recent[:, 0].mean(), "train_landing": recent[:, 1].mean(),
            "train_coverage": recent[:, 2].mean(), **self.last_stats,
            "updates_per_s": (self.updates - updates) / (now - t_mark),
            "env_steps_per_s": (self.env_steps - steps) / (now - t_mark),
        }  # fmt: skip
        row = {
            k: (int(v) if isinstance(v, (int, np.integer)) else float(v)) for k, v in row.items()
        }
        self.history.append(row)
        write_training_log(self.history, self.out, self.maps.log_title)
        return row

    # ------------------------------------------------------------------ checkpoints
    def agent_state(self) -> dict:
        """The agent file's payload: the online network, its rules, config, map and metrics."""
        metrics = {
            k: v
            for k, v in (self.history[-1] if self.history else {}).items()
            if isinstance(v, (int, float))
        }
        payload = agent_payload(
            self.online,
            budget_scale=self.config.input_budget_scale,
            map_name=self.maps.map_name,
            config=self.config.to_dict(),
            metrics=metrics,
            rules=self.config.rule_names(),
            map_digest=self.maps.digest,
        )
        return {**payload, **self.maps.payload()}

    def state(self) -> TrainingState:
        """Everything this run needs to continue exactly."""
        return TrainingState.capture(self)

    def restore(self, state: TrainingState) -> None:
        """Continue from ``state`` (the inverse of :meth:`state`)."""
        state.restore_into(self)
        if self.config.backend == "mujoco":  # physics episodes in flight are lost: end them
            self.replay.terminated[(self.replay.pos - 1) % self.replay.rows] = True  # (n-step)
            self.obs, _ = self.env.reset()  # fresh episodes, from the restored generators
            self.ep_return[:] = 0.0

    def save(self) -> None:
        atomic_save(self.state().to_checkpoint(), self.out / "checkpoint.pt")
        atomic_save(self.agent_state(), self.out / "agent.pt")
        self.last_save = time.perf_counter()

    def resume(self) -> bool:
        """Continue ``checkpoint.pt`` of the run folder (False if there is none); the map source
        refuses a checkpoint of other maps or learning settings (``CheckpointError``)."""
        path = self.out / "checkpoint.pt"
        if not path.exists():
            return False
        checkpoint, config = self.maps.read_resumable(path, self.config)
        state = TrainingState.from_checkpoint(checkpoint)
        if config != self.config:  # the run's own settings where it must keep them
            self.config = config
            self._build_networks()
        self.restore(state)
        return True

    # ------------------------------------------------------------------ the loop
    def run(self, progress: bool = True) -> dict:
        """Train until ``total_updates`` or ``max_minutes``; SIGINT/SIGTERM save a resumable
        checkpoint and raise :class:`TrainingInterrupted`."""
        c = self.config
        self.out.mkdir(parents=True, exist_ok=True)
        self._bar = tqdm(
            total=c.total_updates,
            initial=self.updates,
            disable=not progress,
            unit="upd",
            dynamic_ncols=True,
        )
        self._start = (time.perf_counter(), self.wall_s)
        self._mark = (time.perf_counter(), self.updates, self.env_steps)
        self.last_save = time.perf_counter()
        try:
            with StopSignals() as stop:
                while True:
                    self._drain(stop)  # first: a resumed run may hold update credit
                    self._tick()
                    if stop.received or self._finished():
                        break
                    self.collect()
                    if len(self.replay) >= c.learning_starts and self.replay.can_sample():
                        self.update_credit += c.updates_per_step
                self.save()  # still under StopSignals: a second signal aborts it cleanly
        finally:
            self._bar.close()
        if stop.received:
            raise TrainingInterrupted(stop.received, self.updates, self.out / "checkpoint.pt")
        if c.final_eval:
            res = self.evaluate(full=True)
            res.conditions["training"] = {
                "agent": str(self.out / "agent.pt"), "updates": self.updates,
                "env_steps": self.env_steps, "config": self.config.to_dict(),
            }  # fmt: skip
            res.to_json(self.out / "final_eval.json")
            print(
                f"full protocol ({res.episodes} episodes): landing {res.landing_ratio:.4f}, "
                f"coverage {res.coverage_ratio:.4f}"
            )
        return self.history[-1] if self.history else {}

    def _finished(self) -> bool:
        c = self.config
        out_of_time = bool(c.max_minutes) and self.wall_s >= c.max_minutes * 60
        return self.updates >= c.last_update or out_of_time

    def _clock(self) -> None:
        t0, wall0 = self._start
        self.wall_s = wall0 + time.perf_counter() - t0

    def _drain(self, stop: StopSignals) -> None:
        """The updates the collected steps earned, each followed by its evaluation/checkpoint."""
        c = self.config
        while self.update_credit >= 1.0 and self.updates < c.last_update and not stop.received:
            self.update_credit -= 1.0
            self.update()
            self._bar.update(1)
            if self.updates % c.eval_every == 0 or self.updates == c.last_update:
                self._clock()
                self._evaluate_and_log()
            if self.updates % c.checkpoint_every == 0:
                self._clock()
                self.save()

    def _evaluate_and_log(self) -> None:
        row = self.log(self.evaluate())
        score = (row["eval_return"], row["eval_landing"])  # TrainConfig.best_by
        score = score[::-1] if self.config.best_by == "landing" else score
        if self.best is None or score > self.best:
            self.best = score
            atomic_save(self.agent_state(), self.out / "best.pt")
        self._bar.write(
            f"[{self.updates} upd, {self.episodes} ep, {self.wall_s:.0f}s] "
            f"eval landing {row['eval_landing']:.4f} "
            f"coverage {row['eval_coverage']:.4f} return {row['eval_return']:.2f}"
        )
        self._mark = (time.perf_counter(), self.updates, self.env_steps)

    def _tick(self) -> None:
        """Wall clock, the progress bar's figures and the wall-time checkpoint."""
        c = self.config
        self._clock()
        if (
            c.checkpoint_minutes
            and time.perf_counter() - self.last_save >= c.checkpoint_minutes * 60
        ):
            self.save()
        if self.recent and self.env_steps % (c.num_envs * 20) == 0:
            r = np.array(self.recent, dtype=float)
            self._bar.set_postfix(
                ep=self.episodes,
                ret=f"{r[:, 0].mean():.1f}",
                land=f"{r[:, 1].mean():.3f}",
                cov=f"{r[:, 2].mean():.3f}",
                thr=torch.get_num_threads(),
                refresh=False,
            )
