"""One documented training configuration.

The ``paper`` values (Theile et al. 2020, Table I/II, §III) are reproduced where the paper states
them; the fields marked *speed* are this project's choices for training on a 2-core CPU in minutes
(vectorised collection, replay ratio, n-step targets, learning rate) — the measurements behind each
choice are in ``docs/agent.md``. ``TrainConfig.paper()`` gives the paper's schedule unchanged.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import ClassVar

import torch

from cpp_mujoco.grid.mdp import GridConfig, Rewards
from cpp_mujoco.grid.spaces import MAX_WIND
from cpp_mujoco.grid.way_home import ReturnMargin
from cpp_mujoco.grid.wind import COMPASS, GridWind
from cpp_mujoco.physics.air.turbulence import check_level
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.planners import WIND_PLANNERS

BACKENDS = ("grid", "mujoco")  # where training episodes are flown: the MDP or physics


@dataclass
class TrainConfig:
    # --- task -----------------------------------------------------------------------------
    map: str = "A"  # bundled map name or PNG path
    seed: int = 0
    min_budget: int = 25  # paper: budgets uniform over 25..75 each episode
    max_budget: int = 75
    # wind-robust agents: > 0 trains in the grid's wind option (GridWind: a per-episode wind
    # up to this speed, m/s, sets each action's cost; the network also reads the wind).
    # 0 = the paper's MDP, one unit per action
    wind_max_speed: float = 0.0
    wind_calm_fraction: float = 0.2  # share of training episodes in calm air (wind option)
    # each wind episode's gust spread is the calibrated one times a factor uniform over
    # 1..wind_gust_scale (GridWind.gust_scale; 1 = the calibrated moderate turbulence only)
    wind_gust_scale: float = 1.0
    # the MDP's crash reward while training (paper: −150). With γ = 0.95 a crash 11 moves ahead
    # weighs −85 against +1.2 for a move that shows three new cells, so the greedy policy takes a
    # ≈ 1 % crash risk for it; a larger penalty buys landings with coverage (CHANGELOG.md).
    # Evaluation reports landing and coverage, which do not depend on it
    crash_reward: float = -150.0
    # the MDP's reward per move while training (paper: −0.2). With the discount it makes landing
    # early pay; 0 (with γ near 1) leaves coverage the objective, as the benchmark scores it
    move_reward: float = -0.2
    # start from this agent's weights (bundled name or file; "" = random init). A wind network
    # started from a calm one gets zero weights on its wind inputs: it first acts as that agent
    init_from: str = ""
    # --- backend: where the training episodes are flown ---------------------------------------
    # "grid" (the MDP) or "mujoco": fine-tuning in physics (MixedWindVectorEnv) — the drones fly
    # physics_wind_speed from each of physics_wind_directions with physics_turbulence, and
    # physics_calm_share of them calm, still air. Evaluation (log.csv, best.pt) stays on the grid
    backend: str = "grid"
    physics_wind_speed: float = 9.0  # m/s, the steady wind of the windy slots (0: all calm)
    physics_wind_directions: str = "NESW"  # where it blows from: one group of slots each
    physics_turbulence: str = "moderate"  # Dryden level of the windy slots (none … severe)
    physics_calm_share: float = 0.2  # share of the slots in calm air (rounded to whole slots)
    physics_threads: int = 1  # threads stepping MuJoCo in each weather's group of slots
    # --- DDQN (paper Table I) ----------------------------------------------------------------
    gamma: float = 0.95  # discount factor
    tau: float = 0.01  # soft target update θ̄ ← (1−τ)θ̄ + τθ after each step (paper: 0.005)
    buffer_size: int = 50_000  # replay memory |D|
    batch_size: int = 128  # minibatch m
    beta: float = 0.1  # soft-max exploration temperature, π(a|s) ∝ exp(Q(s,a)/β)
    # --- optimiser (paper: Adam; learning rate not stated) ----------------------------------
    learning_rate: float = 5e-4  # speed: see docs/agent.md
    lr_warmup_updates: int = 200  # speed: linear warm-up from 0 to learning_rate
    # speed: cosine decay of the learning rate to lr_final·learning_rate at total_updates
    # (1.0 = constant) — a quieter end for the greedy policy that is kept
    lr_final: float = 0.1
    adam_eps: float = 1e-5
    loss: str = "huber"  # "mse" (paper) or "huber" (speed: robust to the −150 crash reward)
    max_grad_norm: float = 10.0  # speed: gradient clipping; 0 disables
    # --- collection / schedule -------------------------------------------------------------
    num_envs: int = 32  # speed: environments stepped together, one batched forward per step
    n_step: int = 3  # speed: n-step return targets (1 = paper)
    updates_per_step: float = 1.0  # speed: gradient updates per vector step (of num_envs env steps)
    # speed: guided exploration. DDQN learns off-policy, so part of the collection may follow
    # another behaviour policy: the first guide_fraction of the envs act by a reference planner
    # (with probability guide_epsilon the agent's own soft-max action instead), decaying linearly
    # to no guidance at guide_updates. 0 = the paper's pure soft-max exploration.
    guide: str = "safe-greedy"
    guide_fraction: float = 0.5
    guide_epsilon: float = 0.2
    guide_updates: int = 6_000
    # speed: demonstrations (DQfD, Hester et al. 2018). The reference planner flies every
    # (landing cell, budget) pair once; demo_fraction of every minibatch is drawn from those
    # transitions, which get the TD loss and, weighted by demo_weight, the large-margin loss
    # max_a[Q(s,a) + demo_margin·(a ≠ a_E)] − Q(s,a_E). 0 = no demonstrations (the paper).
    # A general run may name an agent searching with its values: "general+value-beam"
    demo_planner: str = "beam-search"
    demo_fraction: float = 0.5
    demo_margin: float = 0.5  # in reward units: one new target cell is worth 0.4
    demo_weight: float = 1.0
    # the margin the wind planners keep as guide or demonstrator (safe-greedy-wind,
    # beam-search-wind): standard deviations of the way home's spread at gusty wind
    # (ReturnMargin.gusty_sigmas). The agent learns the margin its teachers keep: 6 took B's
    # rated-wind landings from 98.7–98.8 % to 99.6–99.8 % for ~7 points of coverage (CHANGELOG.md)
    wind_planner_sigmas: float = ReturnMargin.gusty_sigmas  # 4, the planners' own
    # act only among the actions after which the way home is still paid (the safe greedy
    # planner's return rule, MapGraph.safe_actions): the soft-max, the greedy policy and the
    # DDQN target's argmax are masked, so every calm-air episode lands by construction and the
    # network learns where to fly, not when to turn home. Off = the paper's agent (calm grid only)
    return_mask: bool = False
    learning_starts: int = 2_000  # env steps collected before the first update
    total_updates: int = 26_000  # training length in gradient updates (≈ 18 min on 2 cores)
    max_minutes: float = 0.0  # stop after this wall-clock time (0 = no limit)
    # end the run at this many updates, keeping the learning-rate and guide schedules of
    # total_updates (0 = at total_updates): the first stage of a staged run, reproducibly
    stop_after_updates: int = 0
    # --- bookkeeping -------------------------------------------------------------------------
    eval_every: int = 1_000  # greedy evaluation every so many updates (all landing cells × …)
    eval_budget_step: int = 1  # … budgets min, min+step, …, max. 1 = the full §7 protocol, on
    # which best.pt is chosen: a subset (every 5th budget) hid crashes at the budgets in between.
    # The final evaluation at the end of a run is always the full protocol, in final_eval.json.
    final_eval: bool = True  # full-protocol evaluation of the final agent → final_eval.json
    # which evaluation best.pt keeps: "return" = the highest greedy return (the paper's
    # objective; a crash weighs −150, i.e. on map A less than a point of coverage) or
    # "landing" = the most landings, then the return (the wind agents' targets put landing first)
    best_by: str = "return"
    checkpoint_every: int = 2_000  # resumable checkpoint every so many updates
    # … and every so many minutes of wall time (0 = off): a kill -9 loses at most this much
    checkpoint_minutes: float = 5.0
    # network input = budget / budget_scale (0 means max_budget). 1 = the raw budget: measured on
    # map A, budget / 75 left the scalar too weak beside 4,096 conv features — the greedy policy
    # flew the same tour for every budget (0 landings below budget 37); raw, it adapts.
    budget_scale: float = 1.0
    device: str = "cpu"
    threads: int = 0  # torch CPU threads; 0 = all available cores (os.cpu_count())

    def __post_init__(self) -> None:
        _check_device(self.device)
        if self.best_by not in ("return", "landing"):
            raise ValueError(f"best_by must be 'return' or 'landing', got {self.best_by!r}")
        if self.loss not in ("mse", "huber"):
            raise ValueError(f"loss must be 'mse' or 'huber', got {self.loss!r}")
        if self.n_step < 1:
            raise ValueError(f"n_step must be >= 1, got {self.n_step}")
        if self.num_envs < 1 or self.batch_size < 1:
            raise ValueError("num_envs and batch_size must be >= 1")
        if self.buffer_size < self.num_envs * (self.n_step + 2):
            raise ValueError(f"buffer_size {self.buffer_size} too small for {self.num_envs} envs")
        if not (math.isfinite(self.crash_reward) and self.crash_reward <= 0):
            raise ValueError(f"crash_reward must be a finite number <= 0, got {self.crash_reward}")
        if not (math.isfinite(self.move_reward) and self.move_reward <= 0):
            raise ValueError(f"move_reward must be a finite number <= 0, got {self.move_reward}")
        if not 0.0 <= self.demo_fraction < 1.0:
            raise ValueError(f"demo_fraction must be in [0, 1), got {self.demo_fraction}")
        if not 0.0 < self.tau <= 1.0 or not 0.0 <= self.gamma <= 1.0 or self.beta <= 0:
            raise ValueError("need 0 < tau <= 1, 0 <= gamma <= 1, beta > 0")
        for name in ("total_updates", "eval_every", "eval_budget_step", "checkpoint_every"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in (
            "max_minutes", "checkpoint_minutes", "budget_scale", "threads", "learning_starts",
            "stop_after_updates",
            "guide_fraction", "updates_per_step", "wind_max_speed", "wind_planner_sigmas",
        ):  # fmt: skip
            if not 0 <= getattr(self, name) < float("inf"):  # NaN fails too
                raise ValueError(f"{name} must be a finite number >= 0, got {getattr(self, name)}")
        if not 0 < self.learning_rate < float("inf"):
            raise ValueError(f"learning_rate must be > 0, got {self.learning_rate}")
        if self.wind_planner_sigmas != ReturnMargin.gusty_sigmas and not self._wind_teacher():
            raise ValueError(
                "wind_planner_sigmas sets the wind planners' margin: it needs guide or "
                "demo_planner safe-greedy-wind or beam-search-wind"
            )
        self.wind  # noqa: B018 - GridWind checks the wind options now, before any run folder
        self._check_backend()
        if self.return_mask and (self.wind_max_speed and not self.MASK_IN_WIND):
            raise ValueError(
                "the per-map agent's return_mask is for calm grid air (use the wind planners as "
                "teachers in wind; the general agent masks in wind too)"
            )
        if self.return_mask and self.backend != "grid":
            raise ValueError(
                "return_mask decides from the grid's budget units; in physics use the return guard"
            )

    # whether this agent's return mask may run in the grid's wind option (the general agent's
    # does: grid/return_rule.py prices the way home at the observed wind)
    MASK_IN_WIND: ClassVar[bool] = False

    def _check_backend(self) -> None:
        if self.backend not in BACKENDS:
            raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {self.backend!r}")
        if self.backend != "grid" and type(self) is not TrainConfig:
            raise ValueError(f"{type(self).__name__} trains on the grid only (backend 'grid')")
        if not 0 <= self.physics_wind_speed <= MAX_WIND:  # NaN fails too
            raise ValueError(f"physics_wind_speed must be in [0, {MAX_WIND:g}] m/s")
        if not 0.0 <= self.physics_calm_share <= 1.0:
            raise ValueError(f"physics_calm_share must be in [0, 1], got {self.physics_calm_share}")
        dirs = self.physics_wind_directions
        if not dirs or set(dirs) - set(COMPASS) or len(set(dirs)) != len(dirs):
            raise ValueError(
                f"physics_wind_directions must be distinct letters of NESW, got {dirs!r}"
            )
        check_level(self.physics_turbulence, PhysicsConfig.altitude)
        if self.physics_threads < 1:
            raise ValueError(f"physics_threads must be >= 1, got {self.physics_threads}")
        if self.backend == "grid":
            return
        windy = any(kw for kw, _ in self.physics_conditions())
        if windy and self.wind is None:
            raise ValueError(
                "physics_wind_speed > 0 needs a network that observes the wind: set "
                "wind_max_speed > 0 (a wind agent), or physics_wind_speed 0 (calm air only)"
            )

    def physics_conditions(self) -> list[tuple[dict, int]]:
        """The weathers of a ``backend="mujoco"`` run: ``[(PhysicsConfig keywords, slots), …]``
        (:class:`~cpp_mujoco.physics.envs.mixed_wind.MixedWindVectorEnv`): calm slots
        first, then the windy ones split evenly over the directions (the first get one more)."""
        n, dirs = self.num_envs, self.physics_wind_directions
        calm = n if not self.physics_wind_speed else int(self.physics_calm_share * n + 0.5)
        windy = n - calm
        if 0 < windy < len(dirs):
            raise ValueError(
                f"num_envs {n} leaves {windy} windy slot(s) for {len(dirs)} wind directions"
            )
        out = [({}, calm)] if calm else []
        for k, d in enumerate(dirs if windy else ""):
            wind = {"wind_speed": self.physics_wind_speed, "turbulence": self.physics_turbulence}
            wind["wind_direction"] = 90.0 * COMPASS.index(d)
            out.append((wind, windy // len(dirs) + (k < windy % len(dirs))))
        return out

    @property
    def wind(self):
        """The grid's wind option this config trains in (None: the paper's unit costs)."""
        if not self.wind_max_speed:
            if self.wind_gust_scale != 1.0:
                raise ValueError("wind_gust_scale needs the wind option (wind_max_speed > 0)")
            return None
        return GridWind(
            max_speed=self.wind_max_speed,
            calm_fraction=self.wind_calm_fraction,
            gust_scale=(1.0, self.wind_gust_scale),
        )

    def _wind_teacher(self) -> bool:
        """Whether a wind planner guides or demonstrates in this run."""
        guide = self.guide if self.guide_fraction > 0 else ""
        demo = self.demo_planner if self.demo_fraction > 0 else ""
        return bool({guide, demo} & set(WIND_PLANNERS))

    @property
    def wind_margin(self) -> ReturnMargin:
        """The margin the wind planners keep as this run's guide and demonstrator."""
        return ReturnMargin(gusty_sigmas=self.wind_planner_sigmas)

    @property
    def grid_config(self):
        """The grid MDP this config trains in: its budgets, wind option, crash and move rewards."""
        return GridConfig(
            min_budget=self.min_budget, max_budget=self.max_budget, wind=self.wind,
            rewards=Rewards(crash=self.crash_reward, move=self.move_reward),
        )  # fmt: skip

    @property
    def input_budget_scale(self) -> float:
        return float(self.budget_scale or self.max_budget)

    @classmethod
    def paper(cls, **overrides) -> TrainConfig:
        """The paper's procedure: one env, one update (batch 128) per env step, 1-step targets,
        MSE loss, no clipping, 10,000 episodes (≈ 500k updates)."""
        base = dict(
            num_envs=1,
            n_step=1,
            updates_per_step=1.0,
            loss="mse",
            max_grad_norm=0.0,
            lr_warmup_updates=0,
            lr_final=1.0,
            learning_rate=1e-4,
            total_updates=500_000,
            learning_starts=128,
            guide_fraction=0.0,
            demo_fraction=0.0,
            tau=0.005,
        )
        return cls(**{**base, **overrides})

    def to_dict(self) -> dict:
        return asdict(self)

    def rule_names(self) -> list[str]:
        """The rules the trained agent acts with (:mod:`~cpp_mujoco.agent.rules`): the return
        mask where it trained with it."""
        return ["return-mask"] if self.return_mask else []

    @property
    def last_update(self) -> int:
        """The update the run ends at: ``stop_after_updates`` if set, else ``total_updates``."""
        return min(self.stop_after_updates or self.total_updates, self.total_updates)

    def learning_rate_at(self, updates: int) -> float:
        """Linear warm-up over ``lr_warmup_updates``, then cosine decay to ``lr_final``·lr."""
        warmup = min(1.0, (updates + 1) / self.lr_warmup_updates) if self.lr_warmup_updates else 1
        progress = min(1.0, updates / max(self.total_updates, 1))
        decay = self.lr_final + (1.0 - self.lr_final) * 0.5 * (1.0 + math.cos(math.pi * progress))
        return self.learning_rate * warmup * float(decay)

    @classmethod
    def from_dict(cls, data: dict) -> TrainConfig:
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in data.items() if k in names})


def _check_device(device: str) -> None:
    """A torch device this machine has, checked before a run folder is touched."""
    try:
        kind = torch.device(device).type
    except (RuntimeError, TypeError):
        raise ValueError(f"device {device!r} is not valid; use cpu, cuda or cuda:N") from None
    if kind == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"device {device!r}: no CUDA GPU is available to this torch build")
    if kind not in ("cpu", "cuda"):
        raise ValueError(f"device {device!r}: only cpu and cuda are supported")
