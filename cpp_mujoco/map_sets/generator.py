"""Random maps, so that agents and planners can be trained and tested beyond the three of the paper.

A generated map has what the paper's maps have, drawn at random (after the map generator of
Theile et al.'s follow-up work, written anew here): a landing zone of a few cells anywhere on the
map (a rectangle or an irregular blob), rectangular no-fly blocks with some irregular blobs and
thin walls among them (and, as an option, a wall across the map with one door, as on map C),
and target regions of varied shape covering 20–60 % of the cells; target regions overlap no-fly
blocks (yellow cells, covered only from beside them), and sometimes a whole block is yellow, as
in map B.

Every drawn map is checked (:func:`check_map`) and drawn again from the same random stream if it
fails, so ``generate(np.random.default_rng(seed), size)`` is one fixed, valid map per seed.
``family="city"`` (a :class:`~cpp_mujoco.map_sets.city.CityConfig`) draws city maps instead:
a street grid of buildings with low obstacles and landing pads (:mod:`cpp_mujoco.map_sets.city`);
the paper-style maps' draws are untouched by it.
Seeds 1,000,000..1,999,999 are reserved for held-out test sets (:mod:`cpp_mujoco.map_sets.sets`):
training must draw its maps from other seeds.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from typing import ClassVar

import numpy as np
from scipy import ndimage

from cpp_mujoco.grid.graph import build_graph
from cpp_mujoco.map_sets.city import CityConfig, draw_city
from cpp_mujoco.map_sets.size_classes import budget_range, map_size
from cpp_mujoco.maps import MAX_SIDE, GridMap, MapError
from cpp_mujoco.util.settings import check_ranges_and_chances, with_options

GENERATOR_VERSION = 1  # bump when a change alters generated maps (held-out sets record it)
MIN_SIZE = 8  # smaller maps leave no room for a landing zone, blocks and targets apart


@dataclass(frozen=True)
class GeneratorConfig:
    """What a generated map looks like (ranges are inclusive).

    Sizes are given for a 16×16 map and scale with the side ``s`` so that no-fly and target
    cover about the same share of any map: a target region's cells by ``(s/16)²``, the number
    of no-fly blocks by ``s/16`` and their sides by ``√(s/16)``. The landing zone grows with the
    side only (a protocol flies from every landing cell, so its cost grows with them).
    """

    family: ClassVar[str] = "paper"
    landing_cells: tuple[int, int] = (4, 16)  # landing zone size (scaled by s/16)
    landing_blob: float = 0.4  # chance the landing zone is an irregular blob, not a rectangle
    nfz_blocks: tuple[int, int] = (1, 5)  # no-fly blocks per map (scaled by s/16)
    nfz_side: tuple[int, int] = (1, 4)  # a block's side (scaled by √(s/16))
    nfz_irregular: float = 0.3  # chance a block is an irregular blob of about the same area
    nfz_wall: float = 0.15  # chance a block is a wall 1–2 cells thick, a quarter to half the side
    target_share: tuple[float, float] = (0.2, 0.6)  # share of all cells that are targets
    target_region_cells: tuple[int, int] = (6, 40)  # cells per target region (scaled by (s/16)²)
    target_irregular: float = 0.4  # chance a target region is a blob, not a rectangle
    yellow_block: float = 0.5  # chance one no-fly block is made target as a whole (yellow)
    # chance of a wall across the whole map, 1–2 cells thick, with one door of 1–2 cells: the
    # far side is reached only through the door, as on the paper's map C (0: the v1 sets'
    # maps, which seldom have one; its draws are made only when it is above 0)
    door_wall: float = 0.0
    max_attempts: int = 100  # maps drawn (and checked) before giving up with an error

    def __post_init__(self) -> None:
        ranges = tuple(f.name for f in fields(self) if str(f.type).startswith("tuple"))
        chances = tuple(f.name for f in fields(self) if f.type == "float")
        check_ranges_and_chances(self, ranges, chances)
        if self.landing_cells[0] < 1 or self.target_region_cells[0] < 1 or self.nfz_side[0] < 1:
            raise ValueError("landing_cells, nfz_side and target_region_cells must be >= 1")
        if not (0.0 < self.target_share[0] and self.target_share[1] < 1.0):
            raise ValueError(f"target_share must lie inside (0, 1), got {self.target_share}")
        if self.max_attempts < 1:
            raise ValueError(f"max_attempts must be >= 1, got {self.max_attempts}")

    @classmethod
    def from_options(cls, config: GeneratorConfig | None = None, **options) -> GeneratorConfig:
        """``config`` with ``options`` replaced; an unknown option is an error naming the known."""
        return with_options(cls, config, "generator", **options)


@dataclass(frozen=True)
class ScatterConfig(GeneratorConfig):
    """Scattered small blocks, a tiny landing pad and target blobs: many obstacles to fly round,
    no room to land on the way and targets in small irregular pieces (the paper-style draw with
    these defaults)."""

    family: ClassVar[str] = "scatter"
    landing_cells: tuple[int, int] = (1, 3)
    landing_blob: float = 0.0
    nfz_blocks: tuple[int, int] = (8, 16)
    nfz_side: tuple[int, int] = (1, 2)
    nfz_irregular: float = 0.2
    nfz_wall: float = 0.0
    target_region_cells: tuple[int, int] = (3, 12)
    target_irregular: float = 0.9
    yellow_block: float = 0.3


@dataclass(frozen=True)
class FieldConfig(GeneratorConfig):
    """Open fields with target patches: hardly a no-fly cell, targets in separate patches with
    open ground between them — the budget, not the obstacles, decides which patches are flown."""

    family: ClassVar[str] = "field"
    landing_cells: tuple[int, int] = (2, 8)
    nfz_blocks: tuple[int, int] = (0, 1)
    nfz_side: tuple[int, int] = (1, 3)
    target_share: tuple[float, float] = (0.15, 0.45)
    target_region_cells: tuple[int, int] = (8, 30)
    target_irregular: float = 0.5
    yellow_block: float = 0.0


FAMILIES: dict[str, type] = {
    "paper": GeneratorConfig, "city": CityConfig, "scatter": ScatterConfig, "field": FieldConfig,
}  # fmt: skip
# a generated map's name starts with it
_PREFIX = {"paper": "gen", "city": "city", "scatter": "scatter", "field": "field"}


def config_from_options(
    config: GeneratorConfig | CityConfig | None = None, family: str | None = None, **options
) -> GeneratorConfig | CityConfig:
    """The generator's config: ``config`` (default: the ``family``'s, "paper" if none) with
    ``options`` (its fields) replaced; an unknown family or option is an error naming the known."""
    if family is not None and family not in FAMILIES:
        raise ValueError(f"unknown map family {family!r}; known: {', '.join(FAMILIES)}")
    cls = FAMILIES[family] if family is not None else type(config or GeneratorConfig())
    if config is not None and not isinstance(config, cls):
        raise ValueError(f"a {type(config).__name__} is not the {family!r} family's config")
    return cls.from_options(config, **options)


# ------------------------------------------------------------------------------------ checks
def check_map(
    grid_map: GridMap, max_budget: int | None = None, fov_side: int = 3, pads: bool = False
) -> None:
    """Raise :class:`MapError` naming the first rule ``grid_map`` breaks, else return.

    The rules (beyond :class:`GridMap`'s own): the landing zone is one 4-connected piece (a
    start anywhere in it is the same mission) — with ``pads`` (city maps) it may be several
    pads, each reachable from the others through flyable cells; and some target cell is seen
    (``fov_side`` square field of view) from a cell the UAV can fly to from the landing zone,
    fly back from and land, all within ``max_budget`` (default: the map's size class maximum)
    — else no policy can cover anything and the map says nothing about a policy.
    """
    if max_budget is None:
        max_budget = budget_range(map_size(grid_map.shape))[1]
    if pads:  # one flyable region holds every pad (moves are 4-connected)
        region, _ = ndimage.label(~grid_map.nfz)
        apart = np.unique(region[grid_map.landing]).size
        if apart != 1:
            raise MapError(
                f"the landing pads are not reachable from one another: they lie in {apart} "
                "flyable regions cut apart by no-fly cells"
            )
    else:
        _, parts = ndimage.label(grid_map.landing)  # the default structure is 4-connectivity
        if parts != 1:
            raise MapError(f"the landing zone is not 4-connected: it has {parts} separate parts")
    g = build_graph(grid_map, fov_side)
    # home = moves to the nearest landing cell + the land; moves between free cells go both
    # ways, so that is also the way out. No-fly cells are never entered, so never visited.
    out_and_back = 2 * (g.home.astype(np.int64) - 1) + 1
    visitable = (out_and_back <= max_budget) & ~grid_map.nfz.reshape(-1)
    if not g.fov_targets[visitable].any():
        raise MapError(
            f"no target cell is visible from a cell the UAV can reach from the landing zone and "
            f"return from within budget {max_budget} (out, back and land)"
        )


# ----------------------------------------------------------------------------------- shapes
def _scale(pair: tuple[int, int], factor: float, minimum: int = 1) -> tuple[int, int]:
    low, high = (max(minimum, round(v * factor)) for v in pair)
    return low, max(low, high)


def _draw_int(rng: np.random.Generator, pair: tuple[int, int]) -> int:
    return int(rng.integers(pair[0], pair[1] + 1))


def _rectangle(rng: np.random.Generator, size: int, height: int, width: int) -> np.ndarray:
    """A ``height`` × ``width`` block (clipped to the map) at a uniformly drawn place."""
    height, width = min(max(height, 1), size), min(max(width, 1), size)
    top = int(rng.integers(0, size - height + 1))
    left = int(rng.integers(0, size - width + 1))
    mask = np.zeros((size, size), dtype=bool)
    mask[top : top + height, left : left + width] = True
    return mask


def _rectangle_of(rng: np.random.Generator, size: int, cells: int) -> np.ndarray:
    """A block of about ``cells`` cells, aspect ratio up to 3:1 either way."""
    aspect = math.exp(rng.uniform(-math.log(3.0), math.log(3.0)))
    height = max(1, round(math.sqrt(cells * aspect)))
    return _rectangle(rng, size, height, max(1, round(cells / height)))


def _neighbours(mask: np.ndarray) -> np.ndarray:
    """Cells 4-adjacent to ``mask`` (and not in it)."""
    near = np.zeros_like(mask)
    near[1:] |= mask[:-1]
    near[:-1] |= mask[1:]
    near[:, 1:] |= mask[:, :-1]
    near[:, :-1] |= mask[:, 1:]
    return near & ~mask


def _blob(
    rng: np.random.Generator, size: int, cells: int, allowed: np.ndarray | None = None
) -> np.ndarray:
    """An irregular 4-connected region of up to ``cells`` cells, grown one random neighbour at a
    time from a random cell (of ``allowed``, if given; empty if none is)."""
    mask = np.zeros((size, size), dtype=bool)
    pool = np.flatnonzero(allowed) if allowed is not None else np.arange(size * size)
    if pool.size == 0:
        return mask
    mask.flat[pool[rng.integers(pool.size)]] = True
    for _ in range(cells - 1):
        frontier = _neighbours(mask)
        if allowed is not None:
            frontier &= allowed
        candidates = np.flatnonzero(frontier)
        if candidates.size == 0:
            break
        mask.flat[candidates[rng.integers(candidates.size)]] = True
    return mask


def _landing_zone(rng: np.random.Generator, size: int, c: GeneratorConfig) -> np.ndarray:
    cells = _draw_int(rng, _scale(c.landing_cells, size / 16))
    if rng.random() < c.landing_blob:
        return _blob(rng, size, cells)
    return _rectangle_of(rng, size, cells)


def _nfz_blocks(rng: np.random.Generator, size: int, c: GeneratorConfig) -> list[np.ndarray]:
    blocks = []
    side = _scale(c.nfz_side, math.sqrt(size / 16))
    for _ in range(_draw_int(rng, _scale(c.nfz_blocks, size / 16, minimum=0))):
        kind = rng.random()
        height, width = _draw_int(rng, side), _draw_int(rng, side)
        if kind < c.nfz_wall:
            length = _draw_int(rng, (max(1, size // 4), max(1, size // 2)))
            thick = _draw_int(rng, (1, 2))
            vertical = rng.random() < 0.5
            block = _rectangle(rng, size, *((length, thick) if vertical else (thick, length)))
        elif kind < c.nfz_wall + c.nfz_irregular:
            block = _blob(rng, size, height * width)
        else:
            block = _rectangle(rng, size, height, width)
        blocks.append(block)
    return blocks


def _door_wall(rng: np.random.Generator, size: int) -> tuple[np.ndarray, np.ndarray]:
    """A wall across the map, 1–2 cells thick, at least 2 cells from the edges it runs along,
    with a door of 1–2 cells; horizontal or vertical. Also the passage: the door and the cell
    before and after it, which no block may close."""
    vertical = rng.random() < 0.5
    thick = _draw_int(rng, (1, 2))
    at = _draw_int(rng, (2, size - 2 - thick))
    door = _draw_int(rng, (1, 2))
    opening = _draw_int(rng, (0, size - door))
    wall = np.zeros((size, size), dtype=bool)
    passage = np.zeros_like(wall)
    wall[at : at + thick] = True
    wall[at : at + thick, opening : opening + door] = False
    passage[at - 1 : at + thick + 1, opening : opening + door] = True
    return (wall.T.copy(), passage.T.copy()) if vertical else (wall, passage)


def _targets(
    rng: np.random.Generator, size: int, c: GeneratorConfig, target: np.ndarray, free: np.ndarray
) -> np.ndarray:
    """Add target regions to ``target`` (only on ``free`` cells) until the drawn share is met;
    each region is at most what is missing (but no smaller than the smallest region)."""
    goal = round(rng.uniform(*c.target_share) * size * size)
    region = _scale(c.target_region_cells, (size / 16) ** 2)
    for _ in range(4 * size * size):  # bound: overlapping regions may add few new cells
        missing = goal - int(target.sum())
        if missing <= 0:
            break
        cells = min(_draw_int(rng, region), max(missing, region[0]))
        if rng.random() < c.target_irregular:
            target |= _blob(rng, size, cells, allowed=free)
        else:
            target |= _rectangle_of(rng, size, cells) & free
    return target


def _draw(rng: np.random.Generator, size: int, c: GeneratorConfig) -> dict[str, np.ndarray]:
    """One unchecked map's layers; the draws always happen in this order (determinism)."""
    landing = _landing_zone(rng, size, c)
    blocks = _nfz_blocks(rng, size, c)
    nfz = np.zeros_like(landing)
    for block in blocks:
        nfz |= block
    if c.door_wall and rng.random() < c.door_wall:  # no draw at 0: the v1 maps stay as they are
        wall, passage = _door_wall(rng, size)
        nfz = (nfz | wall) & ~passage
    nfz &= ~landing
    target = np.zeros_like(landing)
    if blocks and rng.random() < c.yellow_block:
        target |= blocks[int(rng.integers(len(blocks)))] & nfz
    target = _targets(rng, size, c, target, free=~landing)
    return {"landing": landing, "target": target, "nfz": nfz}


# -------------------------------------------------------------------------------- generate
def generate(
    rng: np.random.Generator,
    size: int = 16,
    *,
    config: GeneratorConfig | CityConfig | None = None,
    name: str | None = None,
    **options,
) -> GridMap:
    """A random ``size`` × ``size`` map that passes :func:`check_map` for its size class.

    Maps failing a check are drawn again from ``rng`` (at most ``max_attempts`` times, then a
    :class:`MapError` with the last failure), so the same generator state gives the same map.
    ``options`` override :class:`GeneratorConfig` fields, or with ``family="city"``
    :class:`~cpp_mujoco.map_sets.city.CityConfig` fields. ``name`` defaults to
    ``gen<size>-<digest>`` (``city<size>-<digest>``); :func:`generate_from_seed` names maps by
    their seed.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy Generator (np.random.default_rng(seed)), got {rng!r}")
    if isinstance(size, bool) or not isinstance(size, int | np.integer):
        raise ValueError(f"map size must be an integer, got {size!r}")
    if not MIN_SIZE <= size <= MAX_SIDE:
        raise ValueError(f"map size must be in {MIN_SIZE}..{MAX_SIDE}, got {size}")
    size = int(size)
    config = config_from_options(config, **options)
    city = isinstance(config, CityConfig)
    max_budget = budget_range(size)[1]
    problem = ""
    for _ in range(config.max_attempts):
        try:
            if city:
                grid_map = GridMap(**draw_city(rng, size, config), name=name or "generated")
                check_map(grid_map, max_budget, pads=True)
            else:
                grid_map = GridMap(**_draw(rng, size, config), name=name or "generated")
                check_map(grid_map, max_budget)
        except MapError as exc:
            problem = str(exc)
            continue
        if name:
            return grid_map
        return replace(grid_map, name=f"{_PREFIX[config.family]}{size}-{grid_map.digest[:8]}")
    raise MapError(
        f"no valid {size}x{size} map in {config.max_attempts} attempts (the last: {problem}); "
        "loosen the generator options or raise max_attempts"
    )


def generate_from_seed(seed: int, size: int = 16, **options) -> GridMap:
    """The map of ``seed``, named ``gen<size>-s<seed>`` (``family="city"``: ``city<size>-s<seed>``)
    — with other options than the family's defaults the name also carries the digest, so two
    different maps never share a name."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    config = config_from_options(**options)
    name = f"{_PREFIX[config.family]}{size}-s{seed}"
    grid_map = generate(np.random.default_rng(int(seed)), size, name=name, config=config)
    if config != type(config)():
        grid_map = replace(grid_map, name=f"{name}-{grid_map.digest[:8]}")
    return grid_map


def describe(config: GeneratorConfig | CityConfig | None = None) -> dict:
    """The generator's identity for results: its version, family and options."""
    config = config or GeneratorConfig()
    return {"generator_version": GENERATOR_VERSION, "family": config.family, **asdict(config)}
