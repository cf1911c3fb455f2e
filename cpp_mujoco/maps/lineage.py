"""Maps of the lineage's public simulator (uavSim, Theile et al.) read into the map format.

uavSim's map PNG has one pixel per cell and other colours than ours: any channel value above 0
counts (some of its files store 1, not 255), R = no-fly, G = obstacle, R + G = a building
(obstacle and no-fly), B = landing; alpha means nothing there. It keeps no targets: a mission's
targets come from a second PNG (any non-zero pixel a target; targets under an obstacle are
dropped, as its loader does, and here counted) or are drawn at random over a share of the free
cells. :func:`read_uavsim` reads both into a :class:`~cpp_mujoco.maps.format.GridMap`, so every
command flies the lineage's maps (``cpp-mujoco maps import --format uavsim``). The target
generator (:func:`random_targets`) is written after the idea of theirs, not its code: random
rectangles and ellipses, seeded, hitting the asked share exactly.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from numbers import Real
from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage

from cpp_mujoco.maps.format import MAX_SIDE, GridMap, MapError, read_png


@dataclass(frozen=True)
class TargetShapes:
    """How :func:`random_targets` draws its patches (uavSim's defaults: 3–8 shapes).

    ``count``: how many shapes share the asked cells (each about ``cells / count``, drawn
    0.5–1.5 times that); ``ellipse``: the chance a shape is an ellipse, not a rectangle;
    ``max_aspect``: the longest side over the shortest, at most; ``max_shapes``: shapes drawn
    before the rest is filled from the cells nearest the patches (free cells may be scattered
    so that shapes keep missing them; the fill bounds the work).
    """

    count: tuple[int, int] = (3, 8)
    ellipse: float = 0.5
    max_aspect: float = 3.0
    max_shapes: int = 64

    def __post_init__(self) -> None:
        if len(self.count) != 2 or not 1 <= self.count[0] <= self.count[1]:
            raise ValueError(f"count must be a range (low, high) with low >= 1, got {self.count}")
        if not 0.0 <= self.ellipse <= 1.0:
            raise ValueError(f"ellipse is a probability in 0..1, got {self.ellipse!r}")
        if not self.max_aspect >= 1.0:
            raise ValueError(f"max_aspect must be >= 1, got {self.max_aspect!r}")
        if self.max_shapes < 1:
            raise ValueError(f"max_shapes must be >= 1, got {self.max_shapes!r}")


@dataclass(frozen=True)
class UavsimImport:
    """A uavSim map read: the map, and what became of its targets — ``dropped_targets`` cells of
    the target PNG lay under an obstacle (none if the targets were drawn), ``generated`` says
    the targets were drawn (``seed``, ``fraction`` of the free cells)."""

    grid_map: GridMap
    dropped_targets: int = 0
    generated: bool = False
    fraction: float | None = None
    seed: int | None = None

    def describe(self) -> str:
        """One line on the targets, for the command's report."""
        c = self.grid_map.counts()
        if self.generated:
            return (
                f"targets: {c['target']} cells drawn over {self.fraction:g} of the free cells "
                f"(seed {self.seed})"
            )
        return (
            f"targets: {c['target']} cells from the target PNG, {self.dropped_targets} under an "
            "obstacle dropped"
        )


def _check_fraction(fraction: object) -> float:
    if isinstance(fraction, bool) or not isinstance(fraction, Real):
        raise MapError(f"target fraction must be a number in (0, 1], got {fraction!r}")
    value = float(fraction)
    if not (math.isfinite(value) and 0.0 < value <= 1.0):
        raise MapError(f"target fraction must lie in (0, 1], got {fraction!r}")
    return value


def _check_seed(seed: object) -> int:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise MapError(f"seed must be an integer >= 0, got {seed!r}")
    return int(seed)


def _shape(
    rng: np.random.Generator, shape: tuple[int, int], centre: tuple[int, int], cells: float,
    config: TargetShapes,
) -> np.ndarray:  # fmt: skip
    """A rectangle or an ellipse of about ``cells`` cells around ``centre`` (always holding it)."""
    aspect = math.exp(rng.uniform(-math.log(config.max_aspect), math.log(config.max_aspect)))
    ellipse = rng.random() < config.ellipse
    rows, cols = np.ogrid[: shape[0], : shape[1]]
    if ellipse:  # semi-axes a, b with pi·a·b = cells
        a = max(0.5, math.sqrt(cells * aspect / math.pi))
        b = max(0.5, math.sqrt(cells / (aspect * math.pi)))
        mask = ((rows - centre[0]) / a) ** 2 + ((cols - centre[1]) / b) ** 2 <= 1.0
    else:
        height = max(1, round(math.sqrt(cells * aspect)))
        width = max(1, round(cells / height))
        top, left = centre[0] - (height - 1) // 2, centre[1] - (width - 1) // 2
        mask = (rows >= top) & (rows < top + height) & (cols >= left) & (cols < left + width)
    mask = np.broadcast_to(mask, shape).copy()
    mask[centre] = True
    return mask


def _nearest(candidates: np.ndarray, to: np.ndarray, count: int) -> np.ndarray:
    """The ``count`` cells of ``candidates`` nearest (Euclidean) to the cells of ``to``; ties
    in row-major order."""
    distance = ndimage.distance_transform_edt(~to) if to.any() else np.zeros(to.shape)
    flat = np.flatnonzero(candidates)
    order = flat[np.argsort(distance.reshape(-1)[flat], kind="stable")[:count]]
    chosen = np.zeros(candidates.shape, dtype=bool)
    chosen.flat[order] = True
    return chosen


def random_targets(
    free: np.ndarray, fraction: float, rng: np.random.Generator,
    config: TargetShapes | None = None,
) -> np.ndarray:  # fmt: skip
    """Target patches over ``fraction`` of the ``free`` cells: exactly ``round(fraction · free
    cells)`` of them (at least one), only on free cells. Shapes are centred on a free cell not
    yet a target, so each adds cells; the last is cut to its cells nearest its centre, so the
    share is met exactly. The same ``rng`` state gives the same targets."""
    config = config or TargetShapes()
    fraction = _check_fraction(fraction)
    free = np.asarray(free, dtype=bool)
    available = int(free.sum())
    if available == 0:
        raise MapError("no free cell for targets: every cell is an obstacle or landing")
    goal = max(1, math.floor(fraction * available + 0.5))
    target = np.zeros(free.shape, dtype=bool)
    shapes = int(rng.integers(config.count[0], config.count[1] + 1))
    for _ in range(config.max_shapes):
        missing = goal - int(target.sum())
        if missing <= 0:
            break
        open_cells = np.flatnonzero(free & ~target)
        centre = np.unravel_index(int(open_cells[rng.integers(open_cells.size)]), free.shape)
        cells = goal / shapes * rng.uniform(0.5, 1.5)
        new = _shape(rng, free.shape, (int(centre[0]), int(centre[1])), cells, config)
        new &= free & ~target
        if int(new.sum()) > missing:  # cut to the cells nearest the centre
            seed = np.zeros(free.shape, dtype=bool)
            seed[centre] = True
            new = _nearest(new, seed, missing)
        target |= new
    missing = goal - int(target.sum())
    if missing > 0:  # scattered free cells: the rest beside the patches
        target |= _nearest(free & ~target, target, missing)
    return target


def _read_mask(path: Path, what: str) -> np.ndarray:
    """An image of any mode as a mask: any non-zero colour channel (alpha ignored), as uavSim
    reads its target PNGs; the size is checked before the pixels are decoded."""
    try:
        with Image.open(path) as img:
            w, h = img.size
            if not (1 <= h <= MAX_SIDE and 1 <= w <= MAX_SIDE):
                raise MapError(
                    f"{path}: {what} of {w}x{h} pixels exceeds the map size limit of "
                    f"1..{MAX_SIDE} cells per side"
                )
            if img.mode == "P":
                img = img.convert("RGBA")
            pixels = np.asarray(img)
            colour = pixels[..., :-1] if img.mode in ("LA", "La", "RGBA", "RGBa") else pixels
    except MapError:
        raise
    except FileNotFoundError as e:
        raise MapError(f"{path}: no such {what}") from e
    except Image.DecompressionBombError as e:
        raise MapError(f"{path}: image too large ({e})") from e
    except Exception as e:  # noqa: BLE001 - whatever PIL raises on a bad file is bad input
        raise MapError(f"{path}: unreadable {what} ({type(e).__name__}: {e})") from e
    return colour.reshape(h, w, -1).any(axis=-1)


def _first(mask: np.ndarray) -> str:
    r, c = (int(v) for v in np.argwhere(mask)[0])
    return f"first at (row {r}, col {c})"


def _uavsim_layers(path: Path) -> dict[str, np.ndarray]:
    """The map PNG's landing, no-fly and obstacle layers, checked: landing exists and is
    neither no-fly nor obstacle."""
    colour = read_png(path)[..., :3] > 0
    nfz, obstacle, landing = colour[..., 0], colour[..., 1], colour[..., 2]
    for other, what in ((nfz, "no-fly (red)"), (obstacle, "obstacle (green)")):
        both = landing & other
        if both.any():
            raise MapError(
                f"{path}: {int(both.sum())} landing (blue) cell(s) also {what}, {_first(both)}; "
                "a landing cell must be free"
            )
    if not landing.any():
        raise MapError(f"{path}: no landing cell (blue channel): uavSim's start and land zone")
    return {"landing": landing, "nfz": nfz, "obstacle": obstacle}


def import_uavsim(
    path: str | os.PathLike, targets: str | os.PathLike | None = None,
    target_fraction: float | None = None, seed: int = 0, name: str | None = None,
) -> UavsimImport:  # fmt: skip
    """A uavSim map (``path``) with its targets: from the PNG ``targets`` (same size; cells under
    an obstacle dropped and counted), or drawn over ``target_fraction`` of the free cells
    (neither obstacle nor landing; no-fly cells may hold targets, seen from beside them) from
    ``numpy.random.default_rng(seed)``. Exactly one of ``targets`` and ``target_fraction``.
    Every bad input is a :class:`MapError`; nothing is written."""
    path = Path(path)
    if (targets is None) == (target_fraction is None):
        given = "both" if targets is not None else "neither"
        raise MapError(
            f"a uavSim map keeps no targets: give a target PNG (--targets) or a share of the "
            f"free cells to draw them on (--target-fraction F --seed S), one of them; {given} given"
        )
    fraction = None if target_fraction is None else _check_fraction(target_fraction)
    seed = _check_seed(seed)
    layers = _uavsim_layers(path)
    obstacle = layers["obstacle"]
    dropped = 0
    if targets is not None:
        target_path = Path(targets)
        target = _read_mask(target_path, "target PNG")
        if target.shape != obstacle.shape:
            (h, w), (th, tw) = obstacle.shape, target.shape
            raise MapError(
                f"{target_path}: the target PNG is {tw}x{th} pixels, the map {path} is {w}x{h}; "
                "they must be the same size"
            )
        dropped = int((target & obstacle).sum())
        target = target & ~obstacle
        if not target.any():
            raise MapError(
                f"{target_path}: no target cell left ({dropped} under an obstacle dropped); "
                "a map needs at least one"
            )
    generated = targets is None
    try:
        if generated:
            free = ~obstacle & ~layers["landing"]
            target = random_targets(free, fraction, np.random.default_rng(seed))
        grid_map = GridMap(target=target, name=name or path.stem, source=str(path), **layers)
    except MapError as e:
        raise MapError(f"{path}: {e}") from e
    return UavsimImport(grid_map, dropped, generated, fraction, seed if generated else None)


def read_uavsim(
    path: str | os.PathLike, targets: str | os.PathLike | None = None,
    target_fraction: float | None = None, seed: int = 0,
) -> GridMap:  # fmt: skip
    """The map of :func:`import_uavsim` (which also says how many targets were dropped)."""
    return import_uavsim(path, targets, target_fraction, seed).grid_map
