"""The generated maps a general agent trains and is validated on, padded to one side.

Seeds decide the maps (:func:`~cpp_mujoco.map_sets.generator.generate_from_seed`), so a pool is its
sizes, its count per size and its first seed, and a checkpoint can say exactly what it was
trained on — plus the maps a user brings (:meth:`MapPool.with_named`: the paper's A, B, C or a
site's PNG), recorded by name and digest. Three seed ranges never overlap: training draws below
1,000,000, the held-out test sets own 1,000,000..1,999,999
(:data:`~cpp_mujoco.map_sets.sets.HELDOUT_SEEDS`; a brought map that is one of theirs is
refused) and validation (the maps ``best.pt`` is chosen on) owns :data:`VALIDATION_SEEDS` —
choosing on the test maps, or validating on training maps, would make the reported numbers
optimistic.

Maps of different sizes share a minibatch padded to the pool's largest side with no-fly cells
(:func:`~cpp_mujoco.agent.general_network.pad_grids` says why that changes nothing for the
network); coverage is stored as packed bits of that padded layout (:meth:`MapPool.grids`). Each
map's obstacle layer (:attr:`MapPool.obstacles`, zeros on a map without obstacles and on the
padding) is a property of the map, so a stored state needs nothing more to rebuild it.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from cpp_mujoco.agent.home_input import home_after, home_field
from cpp_mujoco.agent.network import NFZ_CHANNEL, OBSTACLE_CHANNEL
from cpp_mujoco.grid.mdp import GridConfig, Rewards
from cpp_mujoco.grid.return_rule import paid_actions
from cpp_mujoco.grid.way_home import ReturnMargin
from cpp_mujoco.grid.wind import GridWind
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.map_sets.sets import HELDOUT_SEEDS, heldout_set_of
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.maps import GridMap

TRAIN_SEEDS = range(0, 1_000_000)
VALIDATION_SEEDS = range(2_000_000, 3_000_000)
NAMED_SEED = -1  # the seed a pool records for a map it did not generate (MapPool.with_named)


@dataclass
class MapPool:
    """Maps with their size-class grid configs; ``layers`` (M,3,side,side) int8 are the maps
    padded with no-fly cells (bottom and right) to ``side``."""

    maps: list[GridMap]
    seeds: list[int]
    side: int
    configs: list[GridConfig]
    layers: np.ndarray
    # the margin the return rule keeps in wind (:meth:`flown_with`; None: ReturnMargin's default)
    margin: ReturnMargin | None = None
    # the generator options the generated maps were drawn with (empty: the defaults)
    generator: dict = field(default_factory=dict)
    # each map's moves home per padded cell, filled on first use (:meth:`moves_home`; −1: not yet)
    _home: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)
    # and its actions home after each action per padded cell (:meth:`safe_actions`)
    _after: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    @classmethod
    def generate(cls, sizes: tuple[int, ...], per_size: int, first_seed: int, **options) -> MapPool:
        """``per_size`` maps of each size from seeds ``first_seed`` on (the same seeds for
        every size: a seed gives another map at another size), drawn with the generator
        ``options`` (:class:`~cpp_mujoco.map_sets.generator.GeneratorConfig` fields). A
        ``family`` of several joined by ``+`` (``"paper+city"``) is a mix: seed ``first_seed + i``
        is drawn by the ``i``-th family in turn, so every family has its share of every size."""
        if per_size < 1 or not sizes:
            raise ValueError(f"a map pool needs sizes and >= 1 map per size, got {per_size}")
        seeds = [first_seed + i for i in range(per_size)]
        rest = {k: v for k, v in options.items() if k != "family"}
        families = [{"family": f} for f in str(options.get("family", "paper")).split("+")]
        maps, used = [], []
        for size in sizes:
            maps += [
                generate_from_seed(seed, size, **families[i % len(families)], **rest)
                for i, seed in enumerate(seeds)
            ]
            used += seeds
        return cls._of(maps, used, max(sizes), options)

    @classmethod
    def _of(
        cls, maps: list[GridMap], seeds: list[int], side: int, generator: dict | None = None
    ) -> MapPool:
        layers = np.zeros((len(maps), 3, side, side), dtype=np.int8)
        layers[:, NFZ_CHANNEL] = 1
        for i, grid_map in enumerate(maps):
            h, w = grid_map.shape
            layers[i, :, :h, :w] = grid_map.layers
        layers.flags.writeable = False
        configs = {size: size_config(size) for size in {max(m.shape) for m in maps}}
        configs = [configs[max(m.shape)] for m in maps]
        return cls(maps, seeds, side, configs, layers, generator=dict(generator or {}))

    def with_named(self, named: list[GridMap]) -> MapPool:
        """This pool plus maps a user brings (the paper's A, B, C or a site's PNG), each flown
        with its own size class's budgets; their seed is :data:`NAMED_SEED`. ``ValueError`` for
        a map larger than the pool's side or one already in it."""
        digests = {m.digest for m in self.maps}
        for grid_map in named:
            if max(grid_map.shape) > self.side:
                raise ValueError(
                    f"map {grid_map.label} is {grid_map.shape[0]}x{grid_map.shape[1]}: larger "
                    f"than the pool's {self.side}x{self.side} (add its size to --sizes)"
                )
            if grid_map.digest in digests:
                raise ValueError(f"map {grid_map.label} is already in the pool")
            if (held := heldout_set_of(grid_map.digest)) is not None:
                raise ValueError(
                    f"map {grid_map.label} is a map of the held-out set {held}: training on it "
                    "would make that set's numbers optimistic"
                )
            digests.add(grid_map.digest)
        seeds = self.seeds + [NAMED_SEED] * len(named)
        return MapPool._of(self.maps + list(named), seeds, self.side, self.generator)

    def flown_with(
        self,
        wind: GridWind | None,
        margin: ReturnMargin | None = None,
        rewards: Rewards | None = None,
    ) -> MapPool:
        """The same maps flown in the grid's wind option ``wind`` (None: calm air) — every env,
        demonstration and validation episode on the pool draws its wind from it — with
        ``rewards`` (None: the paper's); ``margin``: what the return rule keeps in wind
        (:meth:`safe_actions`)."""
        changes = {"wind": wind, **({"rewards": rewards} if rewards is not None else {})}
        configs = [replace(config, **changes) for config in self.configs]
        return MapPool(
            self.maps, self.seeds, self.side, configs, self.layers, margin, self.generator
        )

    @property
    def wind(self) -> GridWind | None:
        """The wind option the pool's maps are flown in (None: calm air)."""
        return self.configs[0].wind if self.configs else None

    @cached_property
    def obstacles(self) -> np.ndarray:
        """(M,side,side) int8, read-only: each map's obstacle layer padded with zeros (the
        multi-map env's ``obstacle`` observation, the obstacle channel of :meth:`grids`)."""
        layers = np.zeros((len(self), self.side, self.side), dtype=np.int8)
        for i, grid_map in enumerate(self.maps):
            h, w = grid_map.shape
            layers[i, :h, :w] = grid_map.obstacle
        layers.flags.writeable = False
        return layers

    @cached_property
    def has_obstacles(self) -> bool:
        """Whether some map of the pool has obstacles (its observations carry the layer)."""
        return any(m.has_obstacles for m in self.maps)

    @property
    def named(self) -> np.ndarray:
        """Indices of the maps that were not generated (:meth:`with_named`)."""
        return np.flatnonzero(np.asarray(self.seeds) == NAMED_SEED)

    def __len__(self) -> int:
        return len(self.maps)

    @property
    def sizes(self) -> list[int]:
        return sorted({max(m.shape) for m in self.maps})

    @property
    def digest(self) -> str:
        """Fingerprint of every map's cells, in order: a resume refuses another pool."""
        joined = ",".join(m.digest for m in self.maps)
        return hashlib.sha256(joined.encode()).hexdigest()[:12]

    def identity(self) -> dict:
        """What a checkpoint or a result records about the pool."""
        seeds = [s for s in self.seeds if s != NAMED_SEED]
        named = {"named": [f"{self.maps[i].label} ({self.maps[i].digest})" for i in self.named]}
        return {
            "sizes": self.sizes,
            "maps": len(self),
            "seeds": [min(seeds), max(seeds)],
            "side": self.side,
            "digest": self.digest,
            **(named if named["named"] else {}),
            **({"generator": dict(self.generator)} if self.generator else {}),
        }

    def moves_home(self, map_index: np.ndarray, position: np.ndarray) -> np.ndarray:
        """(b,) int32: fewest moves from each stored state's cell (``position``, flat padded
        cell) to a landing cell of its map (``map_index``). A map's field is
        :func:`~cpp_mujoco.agent.home_input.home_field` of its padded layers, computed the first
        time a state of it is asked for (1 ms; the pool's 1,024 maps never all at start)."""
        if self._home is None:
            self._home = np.full((len(self), self.side * self.side), -1, dtype=np.int32)
        map_index = np.asarray(map_index).reshape(-1)
        for m in np.unique(map_index[self._home[map_index, 0] < 0]):  # maps, not cells
            self._home[m] = home_field(self.layers[m])
        return self._home[map_index, np.asarray(position).reshape(-1)]

    def safe_actions(
        self, map_index: np.ndarray, position: np.ndarray, budget, wind=None
    ) -> np.ndarray:
        """(b, 5) bool: the return rule (:func:`~cpp_mujoco.grid.return_rule.paid_actions`) for
        stored states — map by index, flat padded cell, remaining budget, observed wind (None:
        calm air), with the pool's :attr:`margin`."""
        if self._after is None:
            self._after = np.full((len(self), self.side * self.side, 5), -1, dtype=np.int32)
        map_index = np.asarray(map_index).reshape(-1)
        for m in np.unique(map_index[self._after[map_index, 0, 0] < 0]):
            self._after[m] = home_after(self.layers[m])
        after = self._after[map_index, np.asarray(position).reshape(-1)]
        return paid_actions(after, budget, wind, self.margin)

    def grids(
        self,
        map_index: np.ndarray,
        coverage_bits: np.ndarray,
        position: np.ndarray,
        obstacle: bool = False,
    ) -> np.ndarray:
        """(b,5,side,side) float32 network input of stored states: the map's layers, the
        unpacked coverage (padded layout) and the one-hot ``position`` (flat padded cell);
        ``obstacle``: (b,6,side,side), the map's obstacle layer last (:attr:`obstacles`)."""
        b, side = map_index.size, self.side
        grid = np.empty((b, 5 + bool(obstacle), side, side), dtype=np.float32)
        grid[:, :3] = self.layers[map_index]
        cells = side * side
        grid[:, 3] = np.unpackbits(coverage_bits, axis=-1, count=cells).reshape(b, side, side)
        pos = np.zeros((b, cells), dtype=np.float32)
        pos[np.arange(b), position] = 1.0
        grid[:, 4] = pos.reshape(b, side, side)
        if obstacle:
            grid[:, OBSTACLE_CHANNEL] = self.obstacles[map_index]
        return grid


def check_seeds(first_seed: int, count: int, what: str, allowed: range) -> None:
    """``ValueError`` unless seeds first_seed..first_seed+count−1 all lie in ``allowed``
    (:data:`TRAIN_SEEDS` or :data:`VALIDATION_SEEDS`; both avoid the held-out sets)."""
    last = first_seed + count - 1
    if first_seed not in allowed or last not in allowed:
        held = f"; {HELDOUT_SEEDS.start:,}..{HELDOUT_SEEDS.stop - 1:,} are the held-out test sets'"
        raise ValueError(
            f"{what} seeds {first_seed}..{last} must lie in {allowed.start:,}.."
            f"{allowed.stop - 1:,}{held}"
        )


def pad_layout(cells: np.ndarray, shape: tuple[int, int], side: int) -> np.ndarray:
    """(N, h·w) per-cell values of an h×w map → (N, side·side) in the padded layout."""
    n = cells.shape[0]
    out = np.zeros((n, side, side), dtype=cells.dtype)
    out[:, : shape[0], : shape[1]] = cells.reshape(n, *shape)
    return out.reshape(n, side * side)


def padded_cell(cell: np.ndarray, width: int, side: int) -> np.ndarray:
    """Flat cell of a ``width``-wide map → flat cell of the padded layout."""
    row, col = np.divmod(np.asarray(cell), width)
    return row * side + col


class MapwiseGuide:
    """A reference planner for a batch of padded observations on many maps: the planners
    read one map per call (the batch's first), so each map's rows go in their own call, cropped
    back to the map's own size."""

    def __init__(self, planner, pool: MapPool):
        self.planner, self.pool = planner, pool
        self.name = getattr(planner, "name", type(planner).__name__)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        index = np.asarray(obs["map_index"])
        actions = np.zeros(index.size, dtype=np.int64)
        for m in np.unique(index):
            rows = np.flatnonzero(index == m)
            h, w = self.pool.maps[int(m)].shape
            part = {}
            for key, value in obs.items():
                value = np.asarray(value)[rows]
                cells = key in ("map", "coverage", "position", "obstacle")
                part[key] = value[..., :h, :w] if cells else value
            actions[rows] = self.planner.act(part)
        return actions
