"""Named, versioned sets of generated maps: the held-out test sets a general policy is judged on.

A set is a size and a range of seeds of :func:`~cpp_mujoco.map_sets.generator.generate_from_seed`;
``map_sets.json`` beside this module holds each set's definition and the digest of every map, so
a change to the generator that alters a held-out map is caught (:func:`load_map_set` refuses a
set whose maps do not match; a changed set needs a new version, e.g. ``heldout16-v2``).

Held-out sets draw from the reserved seeds :data:`HELDOUT_SEEDS` (1,000,000..1,999,999):
training must use other seeds, or the test is not held out. Regenerate or extend the file with
``python scripts/make_map_sets.py``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from cpp_mujoco.map_sets.generator import GENERATOR_VERSION, generate_from_seed
from cpp_mujoco.map_sets.size_classes import budget_range
from cpp_mujoco.maps import GridMap, MapError

HELDOUT_SEEDS = range(1_000_000, 2_000_000)  # never for training
MAP_SETS_FILE = Path(__file__).resolve().with_name("map_sets.json")


class MapSetError(MapError):
    """An unknown map set, or a set whose regenerated maps differ from the committed digests."""


@dataclass(frozen=True)
class MapSetSpec:
    """A set's definition: ``count`` maps of ``size`` × ``size`` from seeds ``first_seed`` on,
    by generator version ``generator_version`` with the generator ``options`` (pairs of a
    :class:`~cpp_mujoco.map_sets.generator.GeneratorConfig` field and its value, or ``family``
    and a field of that family's config, e.g. ``("family", "city")``; none: the paper-style
    defaults); ``digests`` are the committed maps' digests."""

    name: str
    version: int
    size: int
    first_seed: int
    count: int
    generator_version: int
    digests: tuple[str, ...]
    options: tuple[tuple[str, object], ...] = ()

    @property
    def seeds(self) -> range:
        return range(self.first_seed, self.first_seed + self.count)

    def identity(self, evaluated: int | None = None) -> dict[str, object]:
        """What a result records about the set (``evaluated``: how many of its maps were used,
        the first ones; a partial set is marked so)."""
        used = self.count if evaluated is None else evaluated
        return {
            "name": self.name,
            "version": self.version,
            "size": self.size,
            "size_class_budgets": list(budget_range(self.size)),
            "first_seed": self.first_seed,
            "count": self.count,
            "evaluated": used,
            "complete": used == self.count,
            "generator_version": self.generator_version,
            **({"generator_options": dict(self.options)} if self.options else {}),
        }


@lru_cache(maxsize=1)
def _read(path: Path = MAP_SETS_FILE) -> dict[str, MapSetSpec]:
    data = json.loads(path.read_text())
    specs = {}
    for name, entry in data["sets"].items():
        specs[name] = MapSetSpec(
            name=name,
            version=int(entry["version"]),
            size=int(entry["size"]),
            first_seed=int(entry["first_seed"]),
            count=int(entry["count"]),
            generator_version=int(entry["generator_version"]),
            digests=tuple(entry["digests"]),
            options=tuple(sorted(entry.get("generator_options", {}).items())),
        )
        if len(specs[name].digests) != specs[name].count:
            raise MapSetError(f"{path}: set {name!r} lists {len(entry['digests'])} digests")
    return specs


def map_set_names() -> list[str]:
    """The known sets (``heldout16-v1``, ``heldout32-v1``, ``doors16-v1``, ``city32-v1`` …)."""
    return sorted(_read())


def map_set_spec(name: str) -> MapSetSpec:
    """A set's definition; an unknown name is an error listing the known ones."""
    specs = _read()
    if name not in specs:
        raise MapSetError(f"unknown map set {name!r}; known: {', '.join(sorted(specs))}")
    return specs[name]


def generate_map_set(spec: MapSetSpec, first: int | None = None) -> list[GridMap]:
    """The set's maps (the ``first`` of them, if given) as the generator makes them now."""
    seeds = spec.seeds if first is None else spec.seeds[:first]
    return [generate_from_seed(seed, spec.size, **dict(spec.options)) for seed in seeds]


def load_map_set(name: str, first: int | None = None) -> list[GridMap]:
    """The maps of set ``name`` (only its ``first`` maps, if given), each checked against its
    committed digest: a generator that no longer makes them is an error, never a silent
    change of the test set."""
    spec = map_set_spec(name)
    if first is not None and not 1 <= first <= spec.count:
        raise MapSetError(f"map set {name!r} has {spec.count} maps; cannot take the first {first}")
    if spec.generator_version != GENERATOR_VERSION:
        raise MapSetError(
            f"map set {name!r} was made by generator version {spec.generator_version}, this is "
            f"version {GENERATOR_VERSION}; evaluate it with a release of that version"
        )
    maps = generate_map_set(spec, first)
    for grid_map, expected in zip(maps, spec.digests, strict=False):
        if grid_map.digest != expected:
            raise MapSetError(
                f"map set {name!r}: map {grid_map.name} has digest {grid_map.digest}, the "
                f"committed one is {expected} — the generator changed; a changed held-out set "
                "needs a new version (scripts/make_map_sets.py)"
            )
    return maps


def is_heldout_seed(seed: int) -> bool:
    return seed in HELDOUT_SEEDS


def heldout_set_of(digest: str) -> str | None:
    """The set whose committed maps include the map of ``digest``, or None: a map a user brings
    for training may be a held-out one written out by ``cpp-mujoco maps``."""
    return next((name for name, spec in _read().items() if digest in spec.digests), None)
