"""City-like random maps: the lineage's urban scenes (uavSim's ``manhattan32``, ``urban50``) drawn
at will, for the obstacle layer and the larger size classes.

A city map is a street grid of building blocks — buildings are obstacle and no-fly, some blocks
are split by an alley, some left open (a square), a few are low buildings (obstacle only: flown
over, but hiding what lies behind them) — with low obstacles (trees, masts) and a few no-fly zones
on the open cells, small square landing pads on the streets, and target patches over a share of
the free cells (never under an obstacle or on a pad). Sizes are in cells at any map side: a larger
map is more city, not larger blocks. :func:`draw_city` draws the layers;
:func:`~cpp_mujoco.map_sets.generator.generate` checks them (every pad reachable from every other,
some target seen within the size class's budget) and draws again if they fail.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from cpp_mujoco.maps.lineage import TargetShapes, random_targets
from cpp_mujoco.util.settings import check_ranges_and_chances, with_options

_RANGES = (
    "street_width", "block_side", "low_obstacles", "low_obstacle_length", "nfz_zones",
    "nfz_side", "landing_pads", "pad_side", "target_share", "target_patches",
)  # fmt: skip
_CHANCES = ("building", "low_building", "alley")


@dataclass(frozen=True)
class CityConfig:
    """What a city map looks like (ranges inclusive, in cells; counts marked "per 32×32" scale
    with the map's area, target patches with its side)."""

    family: ClassVar[str] = "city"
    street_width: tuple[int, int] = (2, 3)  # a street between two blocks
    block_side: tuple[int, int] = (3, 7)  # a block's side, each row and column of blocks drawn
    building: float = 0.8  # chance a block is built (else an open square)
    low_building: float = 0.1  # chance a built block is low: obstacle, not no-fly
    alley: float = 0.35  # chance a built block of 3+ cells across is split by a 1-cell alley
    low_obstacles: tuple[int, int] = (2, 6)  # trees, masts on the open cells (per 32×32)
    low_obstacle_length: tuple[int, int] = (1, 3)  # each a line 1 cell thick
    nfz_zones: tuple[int, int] = (0, 2)  # no-fly rectangles over open cells (per 32×32)
    nfz_side: tuple[int, int] = (2, 4)
    landing_pads: tuple[int, int] = (2, 4)  # square pads on street cells
    pad_side: tuple[int, int] = (1, 2)
    target_share: tuple[float, float] = (0.2, 0.5)  # of the free cells (uavSim's default)
    target_patches: tuple[int, int] = (3, 8)  # patches sharing them (uavSim's; per 32 cells)
    max_attempts: int = 100  # maps drawn (and checked) before giving up with an error

    def __post_init__(self) -> None:
        check_ranges_and_chances(self, _RANGES, _CHANCES)
        ones = ("street_width", "block_side", "landing_pads", "pad_side", "target_patches")
        if any(getattr(self, name)[0] < 1 for name in ones):
            raise ValueError(f"{', '.join(ones)} must be >= 1")
        if self.low_obstacle_length[0] < 1 or self.nfz_side[0] < 1:
            raise ValueError("low_obstacle_length and nfz_side must be >= 1")
        if not (0.0 < self.target_share[0] and self.target_share[1] <= 1.0):
            raise ValueError(f"target_share must lie inside (0, 1], got {self.target_share}")
        if self.max_attempts < 1:
            raise ValueError(f"max_attempts must be >= 1, got {self.max_attempts}")

    @classmethod
    def from_options(cls, config: CityConfig | None = None, **options) -> CityConfig:
        """``config`` with ``options`` replaced; an unknown option is an error naming the known."""
        return with_options(cls, config, "city", **options)


def _draw_int(rng: np.random.Generator, pair: tuple[int, int]) -> int:
    return int(rng.integers(pair[0], pair[1] + 1))


def _scaled(pair: tuple[int, int], factor: float) -> tuple[int, int]:
    low = round(pair[0] * factor)
    return low, max(low, round(pair[1] * factor))


def _bands(rng: np.random.Generator, size: int, c: CityConfig) -> tuple[np.ndarray, ...]:
    """Along one axis: each line's block (-1 on a street), where its block starts and how long
    it is. The grid starts at a drawn offset, so a block may touch the edge or a street run
    along it."""
    block = np.full(size, -1)
    start = np.zeros(size, dtype=int)
    length = np.ones(size, dtype=int)
    at, k = _draw_int(rng, (0, c.street_width[1])), 0
    while at < size:  # one pass per block, not per cell
        side = min(_draw_int(rng, c.block_side), size - at)
        block[at : at + side], start[at : at + side], length[at : at + side] = k, at, side
        at, k = at + side + _draw_int(rng, c.street_width), k + 1
    return block, start, length


def _blocks(rng: np.random.Generator, size: int, c: CityConfig) -> tuple[np.ndarray, ...]:
    """(buildings, low buildings, street cells): the street grid and what stands on its blocks."""
    rb, rs, rl = _bands(rng, size, c)
    cb, cs, cl = _bands(rng, size, c)
    shape = (max(int(rb.max()) + 1, 1), max(int(cb.max()) + 1, 1))
    built = rng.random(shape) < c.building
    low = rng.random(shape) < c.low_building
    split = rng.random(shape) < c.alley
    across_rows = rng.random(shape) < 0.5  # the alley runs along a row (else a column)
    where = rng.random(shape)  # the alley's place inside the block
    in_block = (rb[:, None] >= 0) & (cb[None, :] >= 0)
    i, j = np.ix_(np.maximum(rb, 0), np.maximum(cb, 0))
    # an alley line: 1 + floor(u·(side - 2)) from the block's start, inside blocks of side >= 3
    row_alley = (np.arange(size) - rs)[:, None] == 1 + np.floor(where[i, j] * (rl[:, None] - 2))
    col_alley = (np.arange(size) - cs)[None, :] == 1 + np.floor(where[i, j] * (cl[None, :] - 2))
    alley = split[i, j] & np.where(
        across_rows[i, j], row_alley & (rl[:, None] >= 3), col_alley & (cl[None, :] >= 3)
    )
    standing = in_block & built[i, j] & ~alley
    return standing & ~low[i, j], standing & low[i, j], ~in_block


def _lines(
    rng: np.random.Generator, size: int, count: int, length: tuple[int, int], thick: int = 1
) -> np.ndarray:
    """``count`` straight lines (``length`` × ``thick`` cells, either way round) at drawn places."""
    mask = np.zeros((size, size), dtype=bool)
    for _ in range(count):
        long, vertical = _draw_int(rng, length), rng.random() < 0.5
        h, w = (long, thick) if vertical else (thick, long)
        top, left = _draw_int(rng, (0, size - 1)), _draw_int(rng, (0, size - 1))
        mask[top : top + h, left : left + w] = True
    return mask


def _nfz_zones(rng: np.random.Generator, size: int, count: int, side: tuple[int, int]):
    mask = np.zeros((size, size), dtype=bool)
    for _ in range(count):
        h, w = _draw_int(rng, side), _draw_int(rng, side)
        top, left = _draw_int(rng, (0, size - h)), _draw_int(rng, (0, size - w))
        mask[top : top + h, left : left + w] = True
    return mask


def _pads(rng: np.random.Generator, allowed: np.ndarray, count: int, side: tuple[int, int]):
    """Up to ``count`` square pads wholly on ``allowed`` cells, apart from one another (a cell of
    street between); fewer if no place is left."""
    size = allowed.shape[0]
    pads = np.zeros_like(allowed)
    for _ in range(count):
        k = _draw_int(rng, side)
        ok = allowed & ~_grow(pads)
        # windows of k×k allowed cells, by a summed-area table (top-left corners)
        table = np.pad(ok.astype(np.int32).cumsum(0).cumsum(1), ((1, 0), (1, 0)))
        n = size - k + 1
        window = table[k:, k:] - table[:n, k:] - table[k:, :n] + table[:n, :n]
        corners = np.flatnonzero(window == k * k)
        if corners.size == 0:
            continue
        top, left = divmod(int(corners[rng.integers(corners.size)]), n)
        pads[top : top + k, left : left + k] = True
    return pads


def _grow(mask: np.ndarray) -> np.ndarray:
    """``mask`` and its 8 neighbours."""
    grown = mask.copy()
    grown[1:] |= mask[:-1]
    grown[:-1] |= mask[1:]
    out = grown.copy()
    out[:, 1:] |= grown[:, :-1]
    out[:, :-1] |= grown[:, 1:]
    return out


def draw_city(rng: np.random.Generator, size: int, c: CityConfig) -> dict[str, np.ndarray]:
    """One unchecked city map's layers (``landing``, ``target``, ``nfz``, ``obstacle``); the draws
    always happen in this order (determinism)."""
    area, side = (size / 32) ** 2, size / 32
    buildings, low_buildings, street = _blocks(rng, size, c)
    open_cells = ~buildings & ~low_buildings
    nfz = buildings | (_nfz_zones(rng, size, _draw_int(rng, _scaled(c.nfz_zones, area)),
                                  c.nfz_side) & open_cells)  # fmt: skip
    count = _draw_int(rng, _scaled(c.low_obstacles, area))
    low = _lines(rng, size, count, c.low_obstacle_length) & open_cells & ~nfz
    obstacle = buildings | low_buildings | low
    landing = _pads(rng, street & ~nfz & ~obstacle, _draw_int(rng, c.landing_pads), c.pad_side)
    share = float(rng.uniform(*c.target_share))
    patches = _scaled(c.target_patches, side)
    shapes = TargetShapes(count=(max(1, patches[0]), max(1, patches[1])))
    target = random_targets(~obstacle & ~landing, share, rng, shapes)
    return {"landing": landing, "target": target, "nfz": nfz, "obstacle": obstacle}
