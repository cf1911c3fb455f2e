"""The general agent's training configuration: :class:`TrainConfig`'s learning settings plus the
map pool, the network's shape and the validation maps.

Every learning setting (DDQN, optimiser, guide, demonstrations, schedule) means what it means
for the per-map agent and is documented in :mod:`cpp_mujoco.agent.config`; the defaults that
differ here are longer, since the agent must learn a skill instead of one map's tour. Three
inherited fields are not used: ``map`` (the maps come from the generator), ``min_budget`` and
``max_budget`` (each map flies its size class's budgets, :func:`size_classes.budget_range`);
``init_from`` names a general agent of the same network to start from.
"""

from __future__ import annotations

from dataclasses import dataclass

from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.map_pool import TRAIN_SEEDS, VALIDATION_SEEDS, check_seeds
from cpp_mujoco.map_sets.generator import FAMILIES, MIN_SIZE
from cpp_mujoco.map_sets.size_classes import budget_range
from cpp_mujoco.maps import MAX_SIDE

UNUSED = ("map", "min_budget", "max_budget")  # inherited, not options here
NETWORK_FIELDS = ("local_size", "global_size", "conv_filters", "hidden", "num_hidden")
# the general networks: GeneralQNetwork (Theile et al. 2021) and its fully convolutional
# alternative FCNQNetwork, which reads neither local_size nor global_size
ARCHITECTURES = ("global-local", "fcn")
FCN_FIELDS = ("conv_filters", "hidden", "num_hidden")


@dataclass
class GeneralTrainConfig(TrainConfig):
    map: str = "generated"  # unused (see the module docstring)
    # --- maps ---------------------------------------------------------------------------------
    sizes: tuple[int, ...] = (16, 32)  # map sides trained together (one size class each)
    maps_per_size: int = 512  # training maps per size: seeds map_seed .. map_seed + count − 1
    map_seed: int = 0  # first training seed (training seeds stay below 1,000,000)
    episodes_per_map: int = 1  # a slot draws a new map after this many episodes (1: every reset)
    # chance a generated training map has a wall across it with one door (the generator's
    # door_wall; 0: the maps of runs from before the option). Validation maps keep the default
    door_walls: float = 0.0
    # the generator's family of the training and validation maps: "paper" (the paper-style maps
    # of every run before the option), "city" (streets and buildings with obstacles that hide
    # what lies behind them: needs obstacle_input), "scatter", "field"
    # (:data:`~cpp_mujoco.map_sets.generator.FAMILIES`), or several joined by "+"
    # ("paper+scatter+field+city"): the seeds take the families in turn
    map_family: str = "paper"
    # maps a user brings (bundled names or PNG paths: the paper's A B C, a site) trained beside
    # the generated ones, each with its size class's budgets and demonstrations on every one
    named_maps: tuple[str, ...] = ()
    named_share: float = 0.25  # fraction of episodes flown on the named maps (if there are any)
    val_maps_per_size: int = 4  # validation maps per size (best.pt is chosen on them)
    val_seed: int = VALIDATION_SEEDS.start  # first validation seed (2,000,000..2,999,999)
    # demonstrations fly the first demo_maps_per_size maps of each size (all of them if there
    # are fewer), every landing cell ×
    # every demo_budget_step-th budget: about 5 MB a 32×32 map at step 10, 1.5 s of beam search
    demo_maps_per_size: int = 32
    # demonstrations fly only the maps (generated and named) of sides up to this (0: all): the
    # wind planners take about 5 min a 32×32 map at budget step 20 on one core
    demo_max_side: int = 0
    demo_budget_step: int = 10
    # the named maps' demonstrations fly every n-th budget (0: demo_budget_step): a map the
    # user brings is flown at every budget of the protocol, so its tour is shown at every one
    named_demo_budget_step: int = 0
    # fraction of each demonstration minibatch drawn from the named maps (0: uniform over all
    # recorded transitions, so a map weighs as many transitions as its planner flew)
    named_demo_share: float = 0.0
    final_budget_step: int = 1  # the final evaluation's budget step (1: the full protocol)
    # --- network ------------------------------------------------------------------------------
    # "global-local": GeneralQNetwork, Theile et al. 2021 (the fields below are their values);
    # "fcn": FCNQNetwork, fully convolutional with global pooling (conv_filters, hidden,
    # num_hidden and max_side only). The default keeps runs from before the choice resumable
    architecture: str = "global-local"
    local_size: int = 17  # full-resolution crop around the UAV
    global_size: int = 21  # the centred map pooled to this side (63 → 21: 3×3 cells each)
    conv_filters: int = 16  # fcn: the half-resolution layers' (full resolution: half of it)
    hidden: int = 256
    num_hidden: int = 3
    # the canvas fits maps up to this side; fcn: the receptive field covers it (0: the largest
    # of sizes)
    max_side: int = 0
    # the network also reads the fewest moves from the UAV's cell to a landing cell, ÷ the budget
    # scale (:mod:`~cpp_mujoco.agent.home_input`): the safe greedy planner's way home, which a
    # small net must otherwise infer from the pixels of an unseen map. Either architecture.
    # A config stored before the option reads False (:meth:`from_dict`): such runs had none
    home_input: bool = True
    # act among the return rule's safe actions (TrainConfig.return_mask): on for new general
    # runs — the agent must fly unseen maps home every time; a config stored before reads False
    return_mask: bool = True
    # as a policy (validation, the final evaluation, the agent file), also leave out the moves
    # back into a cell flown through since the coverage last grew whose view shows no unseen
    # target (:mod:`~cpp_mujoco.agent.rules.revisit_mask`); training's exploration never uses it.
    # A config stored before the option reads False (:meth:`from_dict`): its agent flew without
    revisit_mask: bool = True
    # as a policy, also do not land while a cell showing an unseen target can be reached and left
    # for home (:mod:`~cpp_mujoco.agent.rules.finish_mask`; the reward's movement penalty and
    # discount make landing early pay); training never uses it. A config stored before reads False
    finish_mask: bool = True
    # global-local only: the network also reads, for each action, the moves from the cell it
    # leads to until the 3×3 view holds an unseen target (:mod:`~cpp_mujoco.agent.target_input`);
    # with --init-from a network without it, the new inputs start at zero weight
    target_input: bool = False
    # the network also reads the map's obstacle layer, one more grid channel
    # (:mod:`~cpp_mujoco.agent.obstacle_input`; zeros on maps without obstacles): without it a
    # policy refuses maps with obstacles. Either architecture; with --init-from a network without
    # it, the new channel starts at zero weight. Off: the networks of runs before the option
    obstacle_input: bool = False
    # train on every named map's images — its 8 rotations and mirror images (a square map;
    # :mod:`cpp_mujoco.maps.symmetry`) — so the network learns the site, not one orientation of it
    named_symmetries: bool = False
    # as a policy (validation, the final evaluation, the agent file), argmax of the Q-values
    # averaged over the map's symmetries (:func:`~cpp_mujoco.grid.symmetry.symmetric_q_values`:
    # 8 readings of one network for a square map); a config stored before reads False
    symmetric_q: bool = False
    # --- defaults that differ from the per-map agent's -----------------------------------------
    buffer_size: int = 200_000  # many maps: a longer memory (≈ 35 MB packed)
    total_updates: int = 200_000  # a skill, not a tour: a GPU or a long CPU run
    guide_updates: int = 50_000
    eval_every: int = 5_000
    eval_budget_step: int = 5  # validation: every 5th budget of each size class
    checkpoint_every: int = 5_000

    def __post_init__(self) -> None:
        if isinstance(self.sizes, (list, int)):  # from a checkpoint or one size
            self.sizes = tuple(self.sizes) if isinstance(self.sizes, list) else (self.sizes,)
        if isinstance(self.named_maps, (list, str)):  # from a checkpoint or one name
            names = self.named_maps
            self.named_maps = tuple(names) if isinstance(names, list) else (names,)
        super().__post_init__()
        if self.architecture not in ARCHITECTURES:
            raise ValueError(
                f"architecture must be one of {', '.join(ARCHITECTURES)}, got {self.architecture!r}"
            )
        if self.architecture == "fcn" and self.target_input:
            raise ValueError("target_input is an input of the global-local network, not fcn's")
        if self.architecture == "fcn" and self.conv_filters < 2:
            raise ValueError(f"conv_filters must be >= 2 for fcn, got {self.conv_filters}")
        if not self.sizes or any(
            type(s) is not int or not MIN_SIZE <= s <= MAX_SIDE for s in self.sizes
        ):
            raise ValueError(f"sizes must be map sides in {MIN_SIZE}..{MAX_SIDE}, got {self.sizes}")
        if len(set(self.sizes)) != len(self.sizes):
            raise ValueError(f"sizes must not repeat, got {self.sizes}")
        for name in ("maps_per_size", "episodes_per_map", "val_maps_per_size", "demo_budget_step",
                     "final_budget_step", *NETWORK_FIELDS):  # fmt: skip
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not 0.0 <= self.door_walls <= 1.0:  # NaN fails too
            raise ValueError(f"door_walls is a chance in 0..1, got {self.door_walls}")
        families = self.map_family.split("+")
        if any(f not in FAMILIES for f in families) or len(set(families)) != len(families):
            raise ValueError(
                f"map_family must be one of {', '.join(FAMILIES)} or several of them joined by "
                f"'+' (each once), got {self.map_family!r}"
            )
        if self.map_family != "paper" and self.door_walls:
            raise ValueError("door_walls are walls of the paper-style maps (map_family=paper)")
        if "city" in families and not self.obstacle_input:
            raise ValueError(
                "city maps have obstacles that hide what the camera sees: train them with "
                "obstacle_input=true (a network without it cannot fly them)"
            )
        if not 0.0 <= self.named_share < 1.0:  # NaN fails too
            raise ValueError(f"named_share must lie in [0, 1), got {self.named_share}")
        if self.named_demo_budget_step < 0:
            raise ValueError(
                f"named_demo_budget_step must be >= 0 (0: demo_budget_step), "
                f"got {self.named_demo_budget_step}"
            )
        if not 0.0 <= self.named_demo_share < 1.0:  # NaN fails too
            raise ValueError(f"named_demo_share must lie in [0, 1), got {self.named_demo_share}")
        if self.named_demo_share and not self.named_maps:
            raise ValueError("named_demo_share > 0 needs named_maps (whose demonstrations)")
        if self.named_maps and not self.named_share:
            raise ValueError("named_maps need named_share > 0 (the share of their episodes)")
        if len(set(self.named_maps)) != len(self.named_maps):
            raise ValueError(f"named_maps must not repeat, got {self.named_maps}")
        if self.demo_maps_per_size < 0:
            raise ValueError(f"demo_maps_per_size must be >= 0, got {self.demo_maps_per_size}")
        if self.demo_fraction > 0 and self.demo_maps_per_size == 0:
            raise ValueError("demo_fraction > 0 needs demo_maps_per_size >= 1")
        if self.demo_max_side < 0 or (
            self.demo_fraction > 0 and self.demo_max_side and self.demo_max_side < min(self.sizes)
        ):
            raise ValueError(
                f"demo_max_side must be 0 (all) or >= the smallest size, got {self.demo_max_side}"
            )
        if self.max_side and self.max_side < max(self.sizes):
            raise ValueError(f"max_side {self.max_side} is smaller than the largest size")
        if self.local_size % 2 != 1 or min(self.local_size, self.global_size) <= 8:
            raise ValueError(
                "local_size must be odd (centred on the UAV) and local_size and global_size "
                f"above 8 (two 5x5 convolutions), got {self.local_size} and {self.global_size}"
            )
        if self.local_size > 2 * self.network_kwargs()["max_side"] - 1:
            raise ValueError(f"local_size {self.local_size} exceeds the centred map's side")
        check_seeds(self.map_seed, self.maps_per_size, "training map", TRAIN_SEEDS)
        check_seeds(self.val_seed, self.val_maps_per_size, "validation map", VALIDATION_SEEDS)

    MASK_IN_WIND = True  # grid/return_rule.py prices the way home at the observed wind

    @classmethod
    def from_dict(cls, data: dict) -> GeneralTrainConfig:
        """A stored config; one without ``home_input``, ``return_mask``, ``revisit_mask`` or
        ``finish_mask`` is from before them: its run had none of them."""
        old = dict.fromkeys(("home_input", "return_mask", "revisit_mask", "finish_mask"), False)
        return super().from_dict({**old, **data})

    def rule_names(self) -> list[str]:
        """The rules the trained agent acts with, in order: the return mask (also a rule of its
        training), then the revisit and finish masks and symmetric Q (of the policy only)."""
        flags = {"return-mask": self.return_mask, "revisit-mask": self.revisit_mask,
                 "finish-mask": self.finish_mask, "symmetric-q": self.symmetric_q}  # fmt: skip
        return [name for name, on in flags.items() if on]

    @property
    def input_budget_scale(self) -> float:
        """budget / this is the network's input; 0 means the largest budget of the sizes."""
        return float(self.budget_scale or max(budget_range(s)[1] for s in self.sizes))

    @property
    def demo_maps(self) -> int:
        """Maps of each size the demonstrations fly."""
        return min(self.demo_maps_per_size, self.maps_per_size)

    def generator_options(self, validation: bool = False) -> dict:
        """The generator options of the training maps (``validation``: of the validation maps,
        which keep the default door walls); empty for the defaults, so pools and their
        identities stay as they were before the options."""
        family = {"family": self.map_family} if self.map_family != "paper" else {}
        walls = {"door_wall": self.door_walls} if self.door_walls and not validation else {}
        return {**family, **walls}

    def network_kwargs(self) -> dict:
        """The arguments of :attr:`architecture`'s network: :class:`~cpp_mujoco.agent.
        general_network.GeneralQNetwork` or :class:`~cpp_mujoco.agent.fcn_network.FCNQNetwork`."""
        names = FCN_FIELDS if self.architecture == "fcn" else NETWORK_FIELDS
        kwargs = {name: getattr(self, name) for name in names}
        return {
            **kwargs,
            "max_side": self.max_side or max(self.sizes),
            "home_input": self.home_input,
            "wind_inputs": bool(self.wind_max_speed),  # a wind agent observes the wind
            **({"target_input": True} if self.target_input else {}),
            **({"obstacle_input": True} if self.obstacle_input else {}),
        }
