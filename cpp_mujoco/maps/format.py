"""Grid maps: boolean layers (landing, target, no-fly, and obstacle) read from PNG files.

PNG format, one pixel per cell, a channel > 0 means set: R = no-fly, G = target, B = landing
(the paper's colours; yellow = target + no-fly). Row 0 is the north edge. An obstacle (a cell
that blocks the camera's line of sight) is a pixel whose alpha is below 255: with red it is a
building (no-fly too: blocks flight and view), without red a low obstacle (flyable, blocks
view). An RGB file, or an RGBA file that is opaque everywhere, has no obstacles.
"""

from __future__ import annotations

import hashlib
import os
import struct
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
from PIL import Image

from cpp_mujoco.util.io import atomic_path
from cpp_mujoco.util.resources import bundled_dir

# The largest map side accepted. Memory grows with the cells (not cells²): the grid env, a 64-env
# batch and both planners on a 256×256 map peak at ~0.7 GB, 128×128 at ~0.13 GB
# (scripts/peak_memory.py; a full protocol from 36 landing cells: 0.8 GB and 0.27 GB). The beam
# search's packed field of view is cells²/8 bytes (0.5 GB at 256×256), so larger maps are
# refused at load rather than risk running out.
MAX_SIDE = 256
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
LAYERS = ("landing", "target", "nfz")  # the observation's map channels, in order
OBSTACLE_ALPHA = 128  # the alpha an obstacle is written with (anything below 255 reads as one)


class MapError(ValueError):
    """A map file or layer set that breaks the map rules; the message names the rule and where."""


def _first_cell(mask: np.ndarray) -> tuple[int, int]:
    r, c = np.argwhere(mask)[0]
    return int(r), int(c)


def _check_size(h: int, w: int, what: str = "map") -> None:
    if not (1 <= h <= MAX_SIDE and 1 <= w <= MAX_SIDE):
        raise MapError(
            f"{what} of {h}x{w} cells exceeds the map size limit of 1..{MAX_SIDE} cells per side"
        )


@dataclass(frozen=True, eq=False)
class GridMap:
    """An H×W map. Arrays are read-only booleans of shape (H, W).

    ``name`` is the bundled name or the file's stem; ``source`` the file it was read from ("" if
    built in memory); ``bundled`` whether it is one of the package's maps (only those carry the
    paper's figures). ``label`` names it in results and file names without ambiguity, and
    ``digest`` fingerprints its cells. ``obstacle`` (None: none) marks the cells that block the
    camera's line of sight (:mod:`cpp_mujoco.grid.occlusion`); it is never a target or landing.
    """

    landing: np.ndarray
    target: np.ndarray
    nfz: np.ndarray
    name: str = "custom"
    source: str = ""
    bundled: bool = False
    obstacle: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.obstacle is None:
            object.__setattr__(self, "obstacle", np.zeros(np.shape(self.landing), dtype=bool))
        layers = {}
        for layer in (*LAYERS, "obstacle"):
            value = np.asarray(getattr(self, layer))
            if value.ndim != 2:
                raise MapError(f"layer {layer!r} must be 2-D, got shape {value.shape}")
            _check_size(*value.shape)  # before copying: never allocate for a map we refuse
            layers[layer] = value.astype(bool, copy=True)
            layers[layer].flags.writeable = False
            object.__setattr__(self, layer, layers[layer])
        shapes = {v.shape for v in layers.values()}
        if len(shapes) != 1:
            raise MapError(
                f"layers have different shapes: { {k: v.shape for k, v in layers.items()} }"
            )
        both = self.landing & self.nfz
        if both.any():
            r, c = _first_cell(both)
            raise MapError(
                f"landing and no-fly overlap in {int(both.sum())} cell(s), "
                f"first at (row {r}, col {c})"
            )
        for layer, what in (("landing", "landing"), ("target", "target")):
            under = self.obstacle & getattr(self, layer)
            if under.any():
                r, c = _first_cell(under)
                raise MapError(
                    f"{int(under.sum())} {what} cell(s) under an obstacle, first at (row {r}, "
                    f"col {c}); an obstacle cell is neither {what} nor seen"
                )
        if not self.landing.any():
            raise MapError("map has no landing cell (blue channel)")
        if not self.target.any():
            raise MapError("map has no target cell (green channel)")

    def __repr__(self) -> str:  # the layers are arrays: a repr of them buries any message
        h, w = self.shape
        return f"GridMap({self.label!r}, {h}x{w}, digest {self.digest})"

    @cached_property
    def digest(self) -> str:
        """:func:`layers_digest` of the map's layers and obstacles."""
        return layers_digest(self.layers, self.obstacle)

    @cached_property
    def has_obstacles(self) -> bool:
        return bool(self.obstacle.any())

    @cached_property
    def label(self) -> str:
        """The name for results and file names: a bundled map's name; another map's name, with
        its digest when the name is also a bundled map's (a user's ``A.png`` is not map A).
        Cached: deciding it lists the bundled maps' folder."""
        if self.bundled or self.name not in bundled_maps():
            return self.name
        return f"{self.name}-{self.digest[:8]}"

    def identity(self) -> dict[str, object]:
        """What a result records about its map."""
        return {
            "map": self.label,
            "map_source": self.source or ("bundled" if self.bundled else "in memory"),
            "map_bundled": self.bundled,
            "map_digest": self.digest,
            "map_shape": list(self.shape),
        }

    @property
    def shape(self) -> tuple[int, int]:
        return self.landing.shape  # type: ignore[return-value]

    @property
    def layers(self) -> np.ndarray:
        """(3, H, W) bool array in observation order: landing, target, no-fly."""
        return np.stack([self.landing, self.target, self.nfz])

    def counts(self) -> dict[str, int]:
        return {layer: int(getattr(self, layer).sum()) for layer in (*LAYERS, "obstacle")}

    def to_rgb(self) -> np.ndarray:
        """(H, W, 3) uint8 image of the three colour layers (obstacles are the file's alpha)."""
        return (np.stack([self.nfz, self.target, self.landing], axis=-1) * 255).astype(np.uint8)

    def to_image(self) -> np.ndarray:
        """The file's pixels: (H, W, 3) RGB, or (H, W, 4) RGBA where the map has obstacles."""
        rgb = self.to_rgb()
        if not self.has_obstacles:
            return rgb
        alpha = np.where(self.obstacle, OBSTACLE_ALPHA, 255).astype(np.uint8)
        return np.concatenate([rgb, alpha[..., None]], axis=-1)

    def save(self, path: str | os.PathLike) -> None:
        """Write as PNG atomically (a crash never leaves a half-written map)."""
        with atomic_path(path) as tmp:
            Image.fromarray(self.to_image()).save(tmp, format="PNG")  # RGB or RGBA by shape

    @classmethod
    def from_ascii(cls, rows: list[str] | str, name: str = "custom") -> GridMap:
        """Build from text: '.' empty, 'L' landing, 'T' target, 'N' no-fly, 'Y' target+no-fly,
        'G' landing+target, 'O' a low obstacle, 'B' a building (obstacle + no-fly). Handy for
        tests and for designing maps."""
        if isinstance(rows, str):
            rows = [r.strip() for r in rows.strip().splitlines() if r.strip()]
        widths = {len(r) for r in rows}
        if len(widths) != 1:
            raise MapError(f"ASCII map rows have different lengths: {sorted(widths)}")
        grid = np.array([list(r) for r in rows])
        unknown = ~np.isin(grid, list(".LTNYGOB"))
        if unknown.any():
            r, c = _first_cell(unknown)
            raise MapError(f"unknown map character {str(grid[r, c])!r} at (row {r}, col {c})")
        return cls(
            landing=np.isin(grid, ["L", "G"]),
            target=np.isin(grid, ["T", "Y", "G"]),
            nfz=np.isin(grid, ["N", "Y", "B"]),
            name=name,
            obstacle=np.isin(grid, ["O", "B"]),
        )


def bundled_maps() -> list[str]:
    """Names of the maps shipped with the package (``A``, ``B``, ``C`` …)."""
    return sorted(p.stem for p in bundled_dir("maps").glob("*.png"))


def _png_header_size(path: Path) -> tuple[int, int] | None:
    """(width, height) from a PNG's IHDR chunk, read without decoding; None if not a PNG."""
    with open(path, "rb") as f:
        head = f.read(24)
    if head[:8] != _PNG_SIGNATURE or head[12:16] != b"IHDR":
        return None
    return struct.unpack(">II", head[16:24])


def read_png(path: Path) -> np.ndarray:
    """The image's RGBA pixels (alpha 255 where the file has none); every failure (a size over
    the limit checked from the header before anything is decoded, a decompression bomb, a broken
    file) is a one-line MapError."""
    try:
        size = _png_header_size(path)
        if size is not None:
            _check_size(size[1], size[0], f"{path}: image")
        with Image.open(path) as img:
            w, h = img.size
            _check_size(h, w, f"{path}: image")
            if img.mode not in ("RGB", "RGBA"):
                raise MapError(f"{path}: image mode {img.mode!r}; a map must be RGB or RGBA")
            return np.asarray(img.convert("RGBA"))
    except MapError:
        raise
    except FileNotFoundError as e:
        raise MapError(f"{path}: no such map file") from e
    except Image.DecompressionBombError as e:  # not an OSError: PIL's own pixel limit
        raise MapError(f"{path}: image too large ({e})") from e
    except Exception as e:  # noqa: BLE001 - whatever PIL raises on a bad file is bad input
        raise MapError(f"{path}: unreadable or truncated PNG ({type(e).__name__}: {e})") from e


def layers_digest(layers: np.ndarray, obstacle: np.ndarray | None = None) -> str:
    """A map's digest from its (3, H, W) layers in observation order and its (H, W) obstacle
    layer: the first 12 hex digits of the SHA-256 of the shape and the layers (the obstacle
    layer only where the map has obstacles: a map without keeps its digest). An observation's
    ``map`` (any 0/1 dtype) gives its map's digest."""
    layers = np.asarray(layers) != 0
    h = hashlib.sha256(repr(tuple(layers.shape[-2:])).encode())
    h.update(np.packbits(layers).tobytes())
    if obstacle is not None and np.any(obstacle):
        h.update(b"obstacle")
        h.update(np.packbits(np.asarray(obstacle) != 0).tobytes())
    return h.hexdigest()[:12]
