"""Training loop: batched collection, DDQN updates, periodic greedy evaluation, checkpoints.

One iteration = one vector step of ``num_envs`` environments (actions from one batched forward pass,
sampled from the soft-max policy) followed by ``updates_per_step`` gradient updates. Every
``eval_every`` updates the greedy policy runs the full evaluation protocol (``cpp_mujoco.evaluate``:
every landing cell × every budget), logged to ``log.csv`` and plotted to ``training.png`` (the
paper's Fig. 4). ``checkpoint.pt`` (training state) and ``agent.pt`` (weights + metadata) are
written atomically; ``best.pt`` keeps the best evaluated agent.
"""

from __future__ import annotations

import csv
import os
import time
from collections import deque
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from tqdm import tqdm

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.agent.checkpoint import (
    TRAIN_KIND,
    CheckpointError,
    agent_payload,
    atomic_save,
    load_checkpoint,
)
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.ddqn import ddqn_update, softmax_actions
from cpp_mujoco.agent.demonstrations import record_demonstrations
from cpp_mujoco.agent.network import QNetwork, observation_to_tensors
from cpp_mujoco.agent.policy import GreedyAgent
from cpp_mujoco.agent.replay import ReplayBuffer
from cpp_mujoco.evaluate import EvaluationResult, evaluate
from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.maps import load_map
from cpp_mujoco.planners import make_planner

LOG_FIELDS = [
    "updates", "env_steps", "episodes", "wall_s", "eval_landing", "eval_coverage", "eval_return",
    "train_return", "train_landing", "train_coverage", "loss", "q", "updates_per_s",
    "env_steps_per_s",
]  # fmt: skip
# per-environment state arrays of GridMDP saved with a training checkpoint (those the MDP has)
_MDP_STATE = (
    "position", "budget", "coverage", "seen_targets", "safety_flag", "landed", "crashed",
    "rejected", "steps", "initial_budget",
)  # fmt: skip


def _mdp_state_names(mdp) -> list[str]:
    return [k for k in _MDP_STATE if isinstance(vars(mdp).get(k), np.ndarray)]


def set_threads(threads: int) -> int:
    n = threads or os.cpu_count() or 1
    torch.set_num_threads(n)
    return n


class ThreadTuner:
    """``threads = 0``: pick the faster torch thread count while training (the CPU is shared).

    Measured on the 2-core machine: one update takes 29 ms with 2 threads vs 56 ms with 1 when the
    machine is idle, but 1,660 ms vs 190 ms when another process holds a core (OpenMP threads
    spin-wait on each other). Every ``period`` updates, ``probe`` updates run with each candidate
    count and the faster one is kept until the next probe.
    """

    def __init__(self, candidates: tuple[int, ...], period: int = 250, probe: int = 4):
        self.candidates, self.period, self.probe = candidates, period, probe
        self.times = {n: [] for n in candidates}
        self.chosen = candidates[-1]

    def before(self, update: int) -> None:
        phase = update % self.period
        k = phase // self.probe
        torch.set_num_threads(self.candidates[k] if k < len(self.candidates) else self.chosen)

    def after(self, update: int, seconds: float) -> None:
        phase = update % self.period
        k = phase // self.probe
        if k < len(self.candidates):
            self.times[self.candidates[k]].append(seconds)
        if phase == self.probe * len(self.candidates) - 1:
            # skip the first probe update of each count (it pays the switch)
            self.chosen = min(
                self.candidates, key=lambda n: np.median(self.times[n][1:] or [np.inf])
            )
            self.times = {n: [] for n in self.candidates}


class Trainer:
    def __init__(self, config: TrainConfig, out_dir: str | os.PathLike):
        self.config = c = config
        self.out = Path(out_dir)
        self.device = torch.device(c.device)
        set_threads(c.threads)
        cores = os.cpu_count() or 1
        self.tuner = ThreadTuner((1, cores)) if c.threads == 0 and cores > 1 else None
        self.grid_map = load_map(c.map)
        self.grid_config = GridConfig(min_budget=c.min_budget, max_budget=c.max_budget)
        self.env = gym.make_vec(
            "cpp_mujoco/Grid-v0",
            num_envs=c.num_envs,
            map=self.grid_map,
            config=self.grid_config,
            autoreset_mode="SameStep",
        )
        torch.manual_seed(c.seed)
        h, w = self.grid_map.shape
        self.online = QNetwork(h, w).to(self.device)
        self.target = QNetwork(h, w).to(self.device)
        self.target.load_state_dict(self.online.state_dict())
        self.optimizer = torch.optim.Adam(
            self.online.parameters(), lr=c.learning_rate, eps=c.adam_eps
        )
        self.replay = ReplayBuffer(
            c.buffer_size, c.num_envs, self.grid_map.layers, c.n_step, c.gamma
        )
        self.rng = np.random.default_rng(c.seed)
        self.guide = make_planner(c.guide) if c.guide_fraction > 0 else None
        self.demos = None
        if c.demo_fraction > 0:
            self.demos = record_demonstrations(
                self.grid_map, self.grid_config, make_planner(c.demo_planner), c.n_step, c.gamma
            )
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
        self.last_eval: tuple[int, int, EvaluationResult] | None = None  # (updates, step, result)

    # ------------------------------------------------------------------ collection and learning
    def collect(self) -> None:
        c = self.config
        grid, budget = observation_to_tensors(self.obs, c.input_budget_scale, self.device)
        with torch.no_grad():
            q = self.online(grid, budget).cpu()
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
            s = _concat(s, self.demos.sample(n_demo, self.rng))
            demo[-n_demo:] = True
        d = self.device
        scale = c.input_budget_scale
        (g, b), (ng, nb) = s["obs"], s["next_obs"]
        return {
            "grid": torch.from_numpy(g).to(d),
            "budget": torch.from_numpy(b / scale).to(d),
            "action": torch.from_numpy(s["action"]).to(d),
            "return": torch.from_numpy(s["return"]).to(d),
            "next_grid": torch.from_numpy(ng).to(d),
            "next_budget": torch.from_numpy(nb / scale).to(d),
            "discount": torch.from_numpy(s["discount"]).to(d),
            "demo": torch.from_numpy(demo).to(d),
        }

    def learning_rate(self) -> float:
        """Linear warm-up over ``lr_warmup_updates``, then cosine decay to ``lr_final``·lr."""
        c = self.config
        warmup = min(1.0, (self.updates + 1) / c.lr_warmup_updates) if c.lr_warmup_updates else 1.0
        progress = min(1.0, self.updates / max(c.total_updates, 1))
        decay = c.lr_final + (1.0 - c.lr_final) * 0.5 * (1.0 + np.cos(np.pi * progress))
        return c.learning_rate * warmup * float(decay)

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
        return GreedyAgent(
            self.online,
            self.config.input_budget_scale,
            self.device,
            name=f"ddqn-{self.grid_map.name}",
        )

    def evaluate(self, full: bool = False) -> EvaluationResult:
        """Greedy evaluation: every landing cell × budgets every ``eval_budget_step`` (or all)."""
        c = self.config
        step = 1 if full else c.eval_budget_step
        if self.last_eval is not None and self.last_eval[:2] == (self.updates, step):
            return self.last_eval[2]  # these weights were just evaluated on these budgets
        budgets = sorted({*range(c.min_budget, c.max_budget + 1, step), c.max_budget})
        res = evaluate(self.agent(), self.grid_map, budgets=budgets, config=self.grid_config)
        self.online.train()
        self.last_eval = (self.updates, step, res)
        return res

    def log(self, row: dict, rate: tuple[float, float]) -> dict:
        recent = np.array(self.recent, dtype=float) if self.recent else np.full((1, 3), np.nan)
        row = {
            "updates": self.updates,
            "env_steps": self.env_steps,
            "episodes": self.episodes,
            "wall_s": round(self.wall_s, 1),
            **row,
            "train_return": recent[:, 0].mean(),
            "train_landing": recent[:, 1].mean(),
            "train_coverage": recent[:, 2].mean(),
            **self.last_stats,
            "updates_per_s": rate[0],
            "env_steps_per_s": rate[1],
        }
        row = {
            k: (int(v) if isinstance(v, (int, np.integer)) else float(v)) for k, v in row.items()
        }
        self.history.append(row)
        path = self.out / "log.csv"
        tmp = path.with_name("log.csv.tmp")
        with open(tmp, "w", newline="") as f:
            writer = csv.DictWriter(f, LOG_FIELDS)
            writer.writeheader()
            writer.writerows(self.history)
        os.replace(tmp, path)
        plot_history(
            self.history,
            self.out / "training.png",
            title=f"DDQN training on map {self.grid_map.name}",
        )
        return row

    # ------------------------------------------------------------------ checkpoints
    def agent_state(self) -> dict:
        metrics = {
            k: v
            for k, v in (self.history[-1] if self.history else {}).items()
            if isinstance(v, (int, float))
        }
        return agent_payload(
            self.online,
            budget_scale=self.config.input_budget_scale,
            map_name=self.grid_map.name,
            config=self.config.to_dict(),
            metrics=metrics,
        )

    def state_dict(self) -> dict:
        mdp = self.env.unwrapped.mdp
        venv = self.env.unwrapped
        return {
            **self.agent_state(),
            "kind": TRAIN_KIND,
            "target": self.target.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "replay": self.replay.state_dict(),
            "env": {
                **{k: torch.from_numpy(np.array(getattr(mdp, k))) for k in _mdp_state_names(mdp)},
                "pending_reset": torch.from_numpy(venv._pending_reset.copy()),
                "rng": venv.np_random.bit_generator.state,
            },
            "obs": {k: torch.from_numpy(np.array(v)) for k, v in self.obs.items()},
            "ep_return": torch.from_numpy(self.ep_return.copy()),
            "rng": self.rng.bit_generator.state,
            "torch_gen": self.torch_gen.get_state(),
            "torch_rng": torch.get_rng_state(),
            "counters": {
                "updates": self.updates,
                "env_steps": self.env_steps,
                "episodes": self.episodes,
                "wall_s": self.wall_s,
                "update_credit": self.update_credit,
            },
            "recent": [list(map(float, r)) for r in self.recent],
            "history": self.history,
            "best": list(self.best) if self.best else None,
        }

    def load_state_dict(self, s: dict) -> None:
        if s.get("kind") != TRAIN_KIND:
            raise CheckpointError(
                "an agent file cannot be resumed; pass a training checkpoint (checkpoint.pt)"
            )
        self.online.load_state_dict(s["network"])
        self.target.load_state_dict(s["target"])
        self.optimizer.load_state_dict(s["optimizer"])
        self.replay.load_state_dict(s["replay"])
        mdp, venv = self.env.unwrapped.mdp, self.env.unwrapped
        for k in _mdp_state_names(mdp):
            setattr(mdp, k, s["env"][k].numpy().copy())
        venv._pending_reset = s["env"]["pending_reset"].numpy().copy()
        venv.np_random.bit_generator.state = s["env"]["rng"]
        self.obs = {k: v.numpy().copy() for k, v in s["obs"].items()}
        self.obs["map"] = mdp.observation()["map"]
        self.ep_return = s["ep_return"].numpy().copy()
        self.rng.bit_generator.state = s["rng"]
        self.torch_gen.set_state(s["torch_gen"])
        torch.set_rng_state(s["torch_rng"])
        for k, v in s["counters"].items():
            setattr(self, k, v)
        self.recent.extend(tuple(r) for r in s["recent"])
        self.history = list(s["history"])
        self.best = tuple(s["best"]) if s["best"] else None

    def save(self) -> None:
        atomic_save(self.state_dict(), self.out / "checkpoint.pt")
        atomic_save(self.agent_state(), self.out / "agent.pt")

    def resume(self) -> bool:
        path = self.out / "checkpoint.pt"
        if not path.exists():
            return False
        state = load_checkpoint(path, map_shape=self.grid_map.shape)
        stored = TrainConfig.from_dict(state["config"])
        if stored.map != self.config.map and load_map(stored.map).name != self.grid_map.name:
            raise CheckpointError(
                f"{path} was trained on map {stored.map!r}, not {self.config.map!r}"
            )
        if (stored.num_envs, stored.buffer_size, stored.n_step) != (
            self.config.num_envs,
            self.config.buffer_size,
            self.config.n_step,
        ):
            raise CheckpointError(
                f"{path}: num_envs/buffer_size/n_step differ from the stored run; "
                "resume with the same settings"
            )
        self.load_state_dict(state)
        return True

    # ------------------------------------------------------------------ the loop
    def run(self, progress: bool = True) -> dict:
        c = self.config
        self.out.mkdir(parents=True, exist_ok=True)
        bar = tqdm(
            total=c.total_updates,
            initial=self.updates,
            disable=not progress,
            unit="upd",
            dynamic_ncols=True,
        )
        t_start, wall0 = time.perf_counter(), self.wall_s
        mark = (time.perf_counter(), self.updates, self.env_steps)
        while self.updates < c.total_updates:
            if c.max_minutes and self.wall_s >= c.max_minutes * 60:
                break
            self.collect()
            if len(self.replay) >= c.learning_starts and self.replay.can_sample():
                self.update_credit += c.updates_per_step
                while self.update_credit >= 1.0 and self.updates < c.total_updates:
                    self.update_credit -= 1.0
                    self.update()
                    bar.update(1)
                    if self.updates % c.eval_every == 0 or self.updates == c.total_updates:
                        self.wall_s = wall0 + time.perf_counter() - t_start
                        now = time.perf_counter()
                        rate = (
                            (self.updates - mark[1]) / (now - mark[0]),
                            (self.env_steps - mark[2]) / (now - mark[0]),
                        )
                        res = self.evaluate()
                        row = self.log(
                            {
                                "eval_landing": res.landing_ratio,
                                "eval_coverage": res.coverage_ratio,
                                "eval_return": float(res.returns.mean()),
                            },
                            rate,
                        )
                        # best = highest greedy return (the objective: crashes weigh −150)
                        score = (row["eval_return"], row["eval_landing"])
                        if self.best is None or score > self.best:
                            self.best = score
                            atomic_save(self.agent_state(), self.out / "best.pt")
                        bar.write(
                            f"[{self.updates} upd, {self.episodes} ep, {self.wall_s:.0f}s] "
                            f"eval landing {row['eval_landing']:.4f} "
                            f"coverage {row['eval_coverage']:.4f} return {row['eval_return']:.2f}"
                        )
                        mark = (time.perf_counter(), self.updates, self.env_steps)
                    if self.updates % c.checkpoint_every == 0:
                        self.wall_s = wall0 + time.perf_counter() - t_start
                        self.save()
            self.wall_s = wall0 + time.perf_counter() - t_start
            if self.recent and self.env_steps % (c.num_envs * 20) == 0:
                r = np.array(self.recent, dtype=float)
                bar.set_postfix(
                    ep=self.episodes,
                    ret=f"{r[:, 0].mean():.1f}",
                    land=f"{r[:, 1].mean():.3f}",
                    cov=f"{r[:, 2].mean():.3f}",
                    thr=torch.get_num_threads(),
                    refresh=False,
                )
        bar.close()
        self.save()
        if c.final_eval:
            res = self.evaluate(full=True)
            res.to_json(self.out / "final_eval.json")
            print(
                f"full protocol ({res.landed.size} episodes): landing {res.landing_ratio:.4f}, "
                f"coverage {res.coverage_ratio:.4f}"
            )
        return self.history[-1] if self.history else {}


def _concat(a: dict, b: dict) -> dict:
    """Concatenate two sampled batches field by field (``obs``/``next_obs`` are pairs)."""
    out = {}
    for k, v in a.items():
        if isinstance(v, tuple):
            out[k] = tuple(np.concatenate([x, y]) for x, y in zip(v, b[k], strict=True))
        else:
            out[k] = np.concatenate([v, b[k]])
    return out


def train(
    config: TrainConfig, out_dir: str | os.PathLike, *, resume: bool = False, progress: bool = True
) -> Trainer:
    """Train (or continue) a run in ``out_dir``; returns the trainer (``.history``, ``.online``)."""
    trainer = Trainer(config, out_dir)
    if resume and not trainer.resume():
        print(f"no checkpoint in {out_dir}; starting a new run")
    trainer.run(progress=progress)
    return trainer


def plot_history(history: list[dict], path: str | os.PathLike, title: str = "") -> None:
    """The paper's Fig. 4: greedy-policy return over training, with landing and coverage ratios."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x = [h["episodes"] for h in history]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    ax1.plot(x, [h["eval_return"] for h in history], color="tab:blue", marker=".")
    ax1.set_ylabel("greedy return (mean)")
    ax1.grid(alpha=0.3)
    ax2.plot(x, [h["eval_landing"] for h in history], label="landing ratio", marker=".")
    ax2.plot(x, [h["eval_coverage"] for h in history], label="coverage ratio", marker=".")
    ax2.set_ylim(0, 1.02)
    ax2.set_xlabel("training episodes")
    ax2.legend(loc="lower right")
    ax2.grid(alpha=0.3)
    if title:
        ax1.set_title(title)
    fig.tight_layout()
    tmp = Path(f"{os.fspath(path)}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)
