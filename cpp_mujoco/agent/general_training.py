"""The general agent's run: ONE agent for maps it has never seen, trained on a pool of maps.

:func:`general_parts` builds its :class:`~cpp_mujoco.agent.training_parts.TrainingParts`, flown
by the same loop as a per-map run (:class:`~cpp_mujoco.agent.train.Trainer`):

* a size-independent network: the global-local
  :class:`~cpp_mujoco.agent.general_network.GeneralQNetwork` or, with ``architecture="fcn"``, the
  fully convolutional :class:`~cpp_mujoco.agent.fcn_network.FCNQNetwork`;
* :class:`~cpp_mujoco.agent.multi_map_env.MultiMapVectorEnv`: every slot on its own generated
  training map, a new one drawn every ``episodes_per_map`` episodes;
* :class:`~cpp_mujoco.agent.multi_map_replay.MultiMapReplay` (each state's map by index) and
  demonstrations recorded map by map (:func:`record_pool_demonstrations`);
* the guide planner map by map (:class:`~cpp_mujoco.agent.map_pool.MapwiseGuide`);
* greedy evaluation on validation maps of disjoint seeds (:class:`MapPoolSource`): the log,
  ``best.pt`` and ``final_eval.json`` (which also holds the safe greedy planner's figures).

The run folder is a per-map run's (``checkpoint.pt`` resumable, ``agent.pt``, ``best.pt``,
``log.csv``, ``training.png``, ``final_eval.json``); its agent files record the architecture, so
:func:`~cpp_mujoco.agent.load_agent` rebuilds the general network.
"""

from __future__ import annotations

from dataclasses import asdict, replace
from pathlib import Path

from cpp_mujoco.agent.checkpoint import CheckpointError, is_general, load_checkpoint
from cpp_mujoco.agent.fcn_network import ARCHITECTURE as FCN
from cpp_mujoco.agent.fcn_network import FCNQNetwork
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_eval import validate
from cpp_mujoco.agent.general_network import ARCHITECTURE as GENERAL
from cpp_mujoco.agent.general_network import GeneralQNetwork, widen_for_wind_inputs
from cpp_mujoco.agent.map_pool import MapPool, MapwiseGuide
from cpp_mujoco.agent.multi_map_env import MultiMapVectorEnv
from cpp_mujoco.agent.multi_map_replay import MultiMapReplay, record_pool_demonstrations
from cpp_mujoco.agent.obstacle_input import widen_for_obstacle_input
from cpp_mujoco.agent.target_input import widen_for_target_input
from cpp_mujoco.agent.training_parts import TrainingParts
from cpp_mujoco.agent.training_state import RESUMABLE_CHANGES, changed_settings
from cpp_mujoco.agent.value_beam import make_demonstrator
from cpp_mujoco.maps import load_map
from cpp_mujoco.maps.symmetry import map_images
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.map_sets import MapSetResult
from cpp_mujoco.protocol.policy import Policy

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
    very network, or of it without ``target_input`` or ``obstacle_input``: widened), or None;
    :class:`CheckpointError` for any other file."""
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
    blind = config.obstacle_input and known and "obstacle_input" not in stored
    if blind:  # a network without the obstacle channel: it starts at zero weight
        kwargs = {k: v for k, v in kwargs.items() if k != "obstacle_input"}
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
    if blind:
        weights = widen_for_obstacle_input(weights, network.grid_layers)
    if calm:
        weights = widen_for_wind_inputs(weights, network)
    if widen:
        return widen_for_target_input(weights, network.features_before_target)
    return weights


def training_pool(config: GeneralTrainConfig, per_size: int | None = None) -> MapPool:
    """The generated training maps (the first ``per_size`` of each size if given: a check)
    plus the config's named ones (``MapError`` for a name or file that is not a map,
    ``ValueError`` for one that does not fit, or has obstacles the network does not read)."""
    options = config.generator_options()
    pool = MapPool.generate(
        config.sizes, per_size or config.maps_per_size, config.map_seed, **options
    )
    if not config.named_maps:
        return pool
    named = [load_map(name) for name in config.named_maps]
    for grid_map in named:
        if grid_map.has_obstacles and not config.obstacle_input:
            raise ValueError(
                f"map {grid_map.label} has obstacles that hide what the camera sees: train "
                "with obstacle_input=true (a network without it cannot fly the map)"
            )
    if config.named_symmetries:
        named = [image for grid_map in named for image in map_images(grid_map)]
    return pool.with_named(named)


class MapPoolSource:
    """The map source of a general run: a pool of generated (and named) training maps, judged on
    validation maps of disjoint seeds."""

    def __init__(self, config: GeneralTrainConfig, pool: MapPool, val_pool: MapPool):
        self.config, self.pool, self.val_pool = config, pool, val_pool
        self.agent_name = "ddqn-general"
        self.log_title = f"DDQN {self.label}"
        self.map_name, self.digest = "generated", pool.digest
        self.judged_on = "validation"

    @property
    def label(self) -> str:
        c = self.config
        sizes = "+".join(str(s) for s in c.sizes)
        named = f" + {', '.join(c.named_maps)}" if c.named_maps else ""
        named += " and their 8 images" if named and c.named_symmetries else ""
        generated = len(self.pool) - len(self.pool.named)
        family = "" if c.map_family == "paper" else f"{c.map_family} "
        wind = f", wind up to {c.wind_max_speed:g} m/s" if c.wind else ""
        return f"general ({generated} generated {family}maps{named}, sizes {sizes}{wind})"

    def budget_step(self, full: bool) -> int:
        return self.config.final_budget_step if full else self.config.eval_budget_step

    def evaluate(self, agent: Policy, budget_step: int) -> MapSetResult:
        """Greedy protocol on the validation maps, every ``budget_step``-th budget."""
        res = validate(agent, self.val_pool, budget_step)
        wind = self.val_pool.wind
        res.conditions = {"validation_maps": self.val_pool.identity(),
                          "train_maps": self.pool.identity(),
                          "wind": None if wind is None else asdict(wind)}  # fmt: skip
        return res

    def complete(self, result: MapSetResult, budget_step: int) -> None:
        """The reference planner flown beside the agent on the same maps and budgets."""
        c = self.config
        reference = WIND_REFERENCE_PLANNER if c.wind else REFERENCE_PLANNER
        if reference not in result.policies:
            planner = make_planner(reference, c.wind_margin)
            result.extend(validate(planner, self.val_pool, budget_step, name=reference))

    def payload(self) -> dict:
        return {"train_maps": self.pool.identity(), "validation_maps": self.val_pool.identity()}

    def read_resumable(
        self, path: Path, config: GeneralTrainConfig
    ) -> tuple[dict, GeneralTrainConfig]:
        state = load_checkpoint(path)
        config = keep_stored_options(config, state)
        check_general_resumable(path, state, config, self.pool)
        return state, config


def keep_stored_options(config: GeneralTrainConfig, state: dict) -> GeneralTrainConfig:
    """A run without the moves home input or the return mask (from before the options, or
    turned off) resumes without them, although new runs default to them: its weights have
    no place for the input, and it learnt its values unmasked. Only that way round —
    dropping either from a run that has it is a changed setting, which
    :func:`check_general_resumable` refuses."""
    try:
        stored = GeneralTrainConfig.from_dict(state["config"])
    except (KeyError, TypeError, ValueError):
        return config  # check_general_resumable says what is wrong with it
    if config.return_mask and not stored.return_mask:
        print("resuming without the return mask, as the run was trained")
        config = replace(config, return_mask=False)
    if config.home_input and not stored.home_input:
        print("resuming without the moves home input, as the run was trained")
        config = replace(config, home_input=False)
    return config


def general_parts(config: GeneralTrainConfig, init: dict | None = None) -> TrainingParts:
    """A general run's parts; ``init``: the starting weights (default:
    :func:`initial_general_weights`)."""
    c = config
    init = init if init is not None else initial_general_weights(c)
    # in the wind option (c.wind; None: calm air) every training, demonstration and
    # validation episode draws its wind, and the return rule keeps the wind planners'
    # margin; training flies the config's crash reward, validation the paper's
    pool = training_pool(c).flown_with(c.wind, c.wind_margin, c.grid_config.rewards)
    options = c.generator_options(validation=True)
    val_pool = MapPool.generate(c.sizes, c.val_maps_per_size, c.val_seed, **options)
    val_pool = val_pool.flown_with(c.wind, c.wind_margin)

    def network(config: GeneralTrainConfig) -> GeneralQNetwork | FCNQNetwork:
        net = build_network(config)
        if init is not None:  # a resume then overwrites these weights
            net.load_state_dict(init)
        return net

    guide = None
    if c.guide_fraction:
        guide = MapwiseGuide(make_planner(c.guide, c.wind_margin), pool)
    return TrainingParts(
        maps=MapPoolSource(c, pool, val_pool),
        env=MultiMapVectorEnv(pool, c.num_envs, c.episodes_per_map, c.named_share),
        replay=MultiMapReplay(c.buffer_size, c.num_envs, pool, c.n_step, c.gamma, c.obstacle_input),
        network=network,
        guide=guide,
        demos=pool_demonstrations(c, pool) if c.demo_fraction > 0 else None,
        fused_adam=True,
    )


def pool_demonstrations(config: GeneralTrainConfig, pool: MapPool):
    """The demo planner's flights on the first ``demo_maps`` maps of each size and on every
    named map (the pool holds ``maps_per_size`` maps of each size in turn)."""
    c = config
    ids = [k * c.maps_per_size + j for k in range(len(c.sizes)) for j in range(c.demo_maps)]
    named = [int(i) for i in pool.named]
    steps = [c.demo_budget_step] * len(ids) + [
        c.named_demo_budget_step or c.demo_budget_step
    ] * len(named)
    ids += named
    if c.demo_max_side:  # only the maps small enough to demonstrate
        kept = [max(pool.maps[i].shape) <= c.demo_max_side for i in ids]
        ids = [i for i, keep in zip(ids, kept, strict=True) if keep]
        steps = [s for s, keep in zip(steps, kept, strict=True) if keep]
    return record_pool_demonstrations(
        pool, ids, make_demonstrator(c.demo_planner, c.wind_margin), c.n_step, c.gamma,
        steps, c.named_demo_share, c.obstacle_input,
    )  # fmt: skip


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
    changed = changed_settings(stored, config.to_dict(), GENERAL_RESUMABLE)
    if changed:
        raise CheckpointError(
            f"{path}: resume with the run's own settings; these differ: {'; '.join(changed)}"
        )
