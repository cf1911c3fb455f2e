"""Training ONE agent for maps it has never seen: the per-map training loop on a pool of maps.

:class:`GeneralTrainer` is the per-map :class:`~cpp_mujoco.agent.train.Trainer` — its
collection, DDQN updates, guided exploration, DQfD minibatches, schedule, signals and checkpoint
loop are inherited unchanged — with other parts plugged in:

* a size-independent network: the global-local
  :class:`~cpp_mujoco.agent.general_network.GeneralQNetwork` or, with ``architecture="fcn"``, the
  fully convolutional :class:`~cpp_mujoco.agent.fcn_network.FCNQNetwork`;
* :class:`~cpp_mujoco.agent.multi_map_env.MultiMapVectorEnv`: every slot on its own generated
  training map, a new one drawn every ``episodes_per_map`` episodes;
* :class:`~cpp_mujoco.agent.multi_map_replay.MultiMapReplay` (each state's map by index) and
  demonstrations recorded map by map (:func:`record_pool_demonstrations`);
* the guide planner map by map (:class:`~cpp_mujoco.agent.map_pool.MapwiseGuide`);
* greedy evaluation on validation maps of disjoint seeds (:func:`general_eval.validate`): the log,
  ``best.pt`` and ``final_eval.json`` (which also holds the safe greedy planner's figures).

The run folder is a per-map run's (``checkpoint.pt`` resumable, ``agent.pt``, ``best.pt``,
``log.csv``, ``training.png``, ``final_eval.json``); its agent files record the architecture, so
:func:`~cpp_mujoco.agent.load_agent` rebuilds the general network.
"""

from __future__ import annotations

import os
import time
from collections import deque
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import torch

from cpp_mujoco.agent.checkpoint import (
    RESUMABLE_CHANGES,
    CheckpointError,
    agent_payload,
    is_general,
    load_checkpoint,
)
from cpp_mujoco.agent.fcn_network import ARCHITECTURE as FCN
from cpp_mujoco.agent.fcn_network import FCNQNetwork
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_eval import ValidationResult, validate
from cpp_mujoco.agent.general_network import ARCHITECTURE as GENERAL
from cpp_mujoco.agent.general_network import GeneralQNetwork, widen_for_wind_inputs
from cpp_mujoco.agent.map_pool import MapPool, MapwiseGuide
from cpp_mujoco.agent.multi_map_env import MultiMapVectorEnv
from cpp_mujoco.agent.multi_map_replay import MultiMapReplay, record_pool_demonstrations
from cpp_mujoco.agent.policy import GreedyAgent
from cpp_mujoco.agent.rules import make_rules
from cpp_mujoco.agent.target_input import widen_for_target_input
from cpp_mujoco.agent.threads import ThreadTuner, set_threads
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.agent.training_run import run_in_folder
from cpp_mujoco.maps import load_map
from cpp_mujoco.maps.symmetry import map_images
from cpp_mujoco.planners import make_planner

# flown on the validation maps beside the final agent: in the wind option the planner that prices
# moves with the observed wind (the calm one's unit costs crash there)
REFERENCE_PLANNER = "safe-greedy"
WIND_REFERENCE_PLANNER = "safe-greedy-wind"
# a resumed general run may also change these: they schedule it, not what it learns
GENERAL_RESUMABLE = RESUMABLE_CHANGES | {
    "final_budget_step", "revisit_mask", "symmetric_q", "finish_mask"
}  # fmt: skip
# GeneralTrainConfig.architecture → (network class, what its checkpoints record)
NETWORKS = {"global-local": (GeneralQNetwork, GENERAL), "fcn": (FCNQNetwork, FCN)}


def build_network(config: GeneralTrainConfig) -> GeneralQNetwork | FCNQNetwork:
    """The config's size-independent network, freshly initialised."""
    return NETWORKS[config.architecture][0](**config.network_kwargs())


def initial_general_weights(config: GeneralTrainConfig) -> dict | None:
    """The weights ``config.init_from`` names (a general agent or run checkpoint of the config's
    very network, or of it without ``target_input``: widened), or None; :class:`CheckpointError`
    for any other file."""
    if not config.init_from:
        return None
    path = Path(config.init_from)
    state = load_checkpoint(path)
    network = build_network(config)
    arch, kwargs = NETWORKS[config.architecture][1], network.kwargs
    stored = state["network_kwargs"]
    known = isinstance(stored, dict)
    widen = config.target_input and known and "target_input" not in stored
    if widen:  # a network without the moves to new targets: they start at zero weight
        kwargs = {k: v for k, v in kwargs.items() if k != "target_input"}
    calm = config.architecture == "global-local" and bool(kwargs.get("wind_inputs"))
    calm = calm and known and stored.get("wind_inputs") is False
    if calm:  # a calm-air network into a wind run: the wind inputs start at zero weight
        kwargs = {**kwargs, "wind_inputs": False}
    if not is_general(state) or state["architecture"] != arch or stored != kwargs:
        raise CheckpointError(
            f"{path} holds {state.get('architecture', 'paper')} {stored}; "
            f"--init-from needs this run's network: {arch} {kwargs}"
        )
    weights = state["network"]
    if calm:
        weights = widen_for_wind_inputs(weights, network)
    if widen:
        return widen_for_target_input(weights, network.features_before_target)
    return weights


def training_pool(config: GeneralTrainConfig, per_size: int | None = None) -> MapPool:
    """The generated training maps (the first ``per_size`` of each size if given: a check)
    plus the config's named ones (``MapError`` for a name or file that is not a map,
    ``ValueError`` for one that does not fit)."""
    options = {"door_wall": config.door_walls} if config.door_walls else {}
    pool = MapPool.generate(
        config.sizes, per_size or config.maps_per_size, config.map_seed, **options
    )
    if not config.named_maps:
        return pool
    named = [load_map(name) for name in config.named_maps]
    if config.named_symmetries:
        named = [image for grid_map in named for image in map_images(grid_map)]
    return pool.with_named(named)


class GeneralTrainer(Trainer):
    def __init__(
        self, config: GeneralTrainConfig, out_dir: str | os.PathLike, init: dict | None = None
    ):
        """``init``: the starting weights (:func:`initial_general_weights`); a resume then
        overwrites them with its own."""
        # not Trainer.__init__, which builds one map's env, network and memory; the attributes
        # set here are those the inherited loop reads
        self.config = c = config
        self.out = Path(out_dir)
        self.device = torch.device(c.device)
        set_threads(c.threads)
        cores = os.cpu_count() or 1
        self.tuner = ThreadTuner((1, cores)) if c.threads == 0 and cores > 1 else None
        # in the wind option (c.wind; None: calm air) every training, demonstration and
        # validation episode draws its wind, and the return rule keeps the wind planners'
        # margin; training flies the config's crash reward, validation the paper's
        rewards = c.grid_config.rewards
        self.pool = training_pool(c).flown_with(c.wind, c.wind_margin, rewards)
        val_pool = MapPool.generate(c.sizes, c.val_maps_per_size, c.val_seed)
        self.val_pool = val_pool.flown_with(c.wind, c.wind_margin)
        self.env = MultiMapVectorEnv(self.pool, c.num_envs, c.episodes_per_map, c.named_share)
        torch.manual_seed(c.seed)
        self._build_networks()
        if init is not None:
            self.online.load_state_dict(init)
            self.target.load_state_dict(init)
        self.replay = MultiMapReplay(c.buffer_size, c.num_envs, self.pool, c.n_step, c.gamma)
        self.rng = np.random.default_rng(c.seed)
        self.guide = None
        if c.guide_fraction:
            self.guide = MapwiseGuide(make_planner(c.guide, c.wind_margin), self.pool)
        self.demos = None
        if c.demo_fraction > 0:
            # the pool holds maps_per_size maps of each size in turn: the first of each size,
            # and every named map
            ids = [k * c.maps_per_size + j for k in range(len(c.sizes)) for j in range(c.demo_maps)]
            named = [int(i) for i in self.pool.named]
            steps = [c.demo_budget_step] * len(ids) + [
                c.named_demo_budget_step or c.demo_budget_step
            ] * len(named)
            ids += named
            if c.demo_max_side:  # only the maps small enough to demonstrate
                kept = [max(self.pool.maps[i].shape) <= c.demo_max_side for i in ids]
                ids = [i for i, keep in zip(ids, kept, strict=True) if keep]
                steps = [s for s, keep in zip(steps, kept, strict=True) if keep]
            self.demos = record_pool_demonstrations(
                self.pool, ids, make_planner(c.demo_planner, c.wind_margin), c.n_step, c.gamma,
                steps, c.named_demo_share,
            )  # fmt: skip
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
        self.last_eval: tuple[int, int, ValidationResult] | None = None
        self.last_save = time.perf_counter()

    def _build_networks(self) -> None:
        """The online and target networks of the config, and their optimiser."""
        c = self.config
        self.online = build_network(c).to(self.device)
        self.target = build_network(c).to(self.device)
        self.target.load_state_dict(self.online.state_dict())
        self.optimizer = torch.optim.Adam(
            self.online.parameters(), lr=c.learning_rate, eps=c.adam_eps, fused=self._fused()
        )

    @property
    def label(self) -> str:
        sizes = "+".join(str(s) for s in self.config.sizes)
        named = f" + {', '.join(self.config.named_maps)}" if self.config.named_maps else ""
        named += " and their 8 images" if named and self.config.named_symmetries else ""
        generated = len(self.pool) - len(self.pool.named)
        wind = f", wind up to {self.config.wind_max_speed:g} m/s" if self.config.wind else ""
        return f"general ({generated} generated maps{named}, sizes {sizes}{wind})"

    # ------------------------------------------------------------------ evaluation and logging
    def agent(self) -> GreedyAgent:
        return GreedyAgent(
            self.online, self.config.input_budget_scale, self.device, name="ddqn-general",
            rules=make_rules(self.config.rule_names(), self.config.wind_margin),
        )  # fmt: skip

    def evaluate(self, full: bool = False) -> ValidationResult:
        """Greedy protocol on the validation maps, every ``eval_budget_step``-th budget; the
        final evaluation (``full``) every ``final_budget_step``-th, with the reference planner."""
        c = self.config
        step = c.final_budget_step if full else c.eval_budget_step
        if self.last_eval is not None and self.last_eval[:2] == (self.updates, step):
            res = self.last_eval[2]  # these weights were just validated on these budgets
        else:
            res = validate(self.agent(), self.val_pool, step)
            wind = self.val_pool.wind
            res.conditions = {"validation_maps": self.val_pool.identity(),
                              "train_maps": self.pool.identity(),
                              "wind": None if wind is None else asdict(wind)}  # fmt: skip
            self.online.train()
            self.last_eval = (self.updates, step, res)
        reference = WIND_REFERENCE_PLANNER if c.wind else REFERENCE_PLANNER
        if full and reference not in res.references:
            planner = make_planner(reference, c.wind_margin)
            res.references[reference] = validate(planner, self.val_pool, step).summary()
        return res

    def log_title(self) -> str:
        """:meth:`Trainer.log`'s row, under the general agent's title."""
        return f"DDQN {self.label}"

    # ------------------------------------------------------------------ checkpoints
    def agent_state(self) -> dict:
        metrics = {
            k: v
            for k, v in (self.history[-1] if self.history else {}).items()
            if isinstance(v, (int, float))
        }
        payload = agent_payload(
            self.online,
            budget_scale=self.config.input_budget_scale,
            map_name="generated",
            config=self.config.to_dict(),
            metrics=metrics,
            rules=self.config.rule_names(),
            map_digest=self.pool.digest,
        )
        payload["train_maps"] = self.pool.identity()
        payload["validation_maps"] = self.val_pool.identity()
        return payload

    def _fused(self) -> bool | None:
        """Adam's fused step where torch has one: the same update, measured 0.9 ms instead of
        8 ms per step on the CPU (the per-tensor loop's Python overhead)."""
        return True if self.device.type in ("cpu", "cuda") else None

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        for group in self.optimizer.param_groups:  # a checkpoint's groups carry their own flag
            group["fused"], group["foreach"] = self._fused(), None
            for p in group["params"]:  # the fused step keeps its count beside the parameter
                st = self.optimizer.state.get(p, {})
                if "step" in st:
                    st["step"] = torch.as_tensor(st["step"], dtype=torch.float32, device=p.device)

    def resume(self) -> bool:
        """Load ``checkpoint.pt`` from the run folder (False if there is none); refuses one of
        another architecture, map pool or learning settings."""
        path = self.out / "checkpoint.pt"
        if not path.exists():
            return False
        state = load_checkpoint(path)
        self._keep_stored_options(state)
        check_general_resumable(path, state, self.config, self.pool)
        self.load_state_dict(state)
        return True

    def _keep_stored_options(self, state: dict) -> None:
        """A run without the moves home input or the return mask (from before the options, or
        turned off) resumes without them, although new runs default to them: its weights have
        no place for the input, and it learnt its values unmasked. Only that way round —
        dropping either from a run that has it is a changed setting, which
        :func:`check_general_resumable` refuses."""
        try:
            stored = GeneralTrainConfig.from_dict(state["config"])
        except (KeyError, TypeError, ValueError):
            return  # check_general_resumable says what is wrong with it
        if self.config.return_mask and not stored.return_mask:
            print("resuming without the return mask, as the run was trained")
            self.config = replace(self.config, return_mask=False)
        if self.config.home_input and not stored.home_input:
            print("resuming without the moves home input, as the run was trained")
            self.config = replace(self.config, home_input=False)
            self._build_networks()


def check_general_resumable(
    path: Path, state: dict, config: GeneralTrainConfig, pool: MapPool
) -> None:
    """:class:`CheckpointError` unless ``state`` continues this general run: the same general
    network, the same training maps and the same learning settings (:data:`GENERAL_RESUMABLE`
    may differ)."""
    if not is_general(state):
        raise CheckpointError(f"{path} is a per-map run; resume it with `cpp-mujoco train`")
    if state["architecture"] != NETWORKS[config.architecture][1]:
        stored = {name: arch for arch, (_, name) in NETWORKS.items()}[state["architecture"]]
        raise CheckpointError(
            f"{path} holds the {stored} network; resume with --architecture {stored} "
            f"(given: {config.architecture})"
        )
    if state.get("map_digest") != pool.digest:
        raise CheckpointError(
            f"{path} was trained on another map pool ({state.get('train_maps')}); "
            f"this run's is {pool.identity()}"
        )
    try:
        stored = GeneralTrainConfig.from_dict(state["config"]).to_dict()
    except (TypeError, ValueError) as exc:
        raise CheckpointError(f"{path}: its stored config is invalid ({exc})") from None
    given = config.to_dict()
    changed = [
        f"{k} {stored[k]!r} (stored) vs {given[k]!r} (given)"
        for k in given
        if k not in GENERAL_RESUMABLE and given[k] != stored[k]
    ]
    if changed:
        raise CheckpointError(
            f"{path}: resume with the run's own settings; these differ: {'; '.join(changed)}"
        )


def train_general(
    config: GeneralTrainConfig,
    out_dir: str | os.PathLike,
    *,
    resume: bool = False,
    overwrite: bool = False,
    progress: bool = True,
) -> GeneralTrainer:
    """Train (or continue) a general run in ``out_dir``, locked meanwhile, as
    :func:`~cpp_mujoco.agent.training_run.train` does for one map; returns the trainer."""
    init = initial_general_weights(config)  # a bad file fails before the folder is claimed
    training_pool(config, per_size=1)  # and so does a named map that is not one or does not fit
    return run_in_folder(
        lambda out: GeneralTrainer(config, out, init), out_dir,
        resume=resume, overwrite=overwrite, progress=progress,
    )  # fmt: skip
