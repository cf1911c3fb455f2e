"""Size classes: which movement budgets a map of a given size is flown and evaluated with.

The paper flies 16×16 maps with budgets 25..75. A larger map needs proportionally longer flights
to reach its far side and come back, so budgets scale with the side: 32×32 → 50..150. 50×50 maps
fly 150..250, as the lineage flies its 50×50 urban scenes (Theile et al., ICAR 2021), not the
scaled 78..234: their streets and buildings make the way out and back longer than open maps'.
This is the one place that says so — the map generator's reachability check, map sets and
their protocol all take their budgets from :func:`budget_range`.
"""

from __future__ import annotations

from typing import Any

from cpp_mujoco.grid.mdp import GridConfig

# side → (min budget, max budget); other sides scale the paper's 16 → 25..75 linearly
SIZE_CLASSES: dict[int, tuple[int, int]] = {16: (25, 75), 32: (50, 150), 50: (150, 250)}
_PAPER_SIDE, _PAPER_MIN, _PAPER_MAX = 16, 25, 75


def budget_range(size: int) -> tuple[int, int]:
    """(min, max) budget of maps whose larger side is ``size``: :data:`SIZE_CLASSES`, else the
    paper's range scaled by ``size / 16`` (rounded to the nearest whole unit)."""
    if size < 1:
        raise ValueError(f"map size must be >= 1, got {size}")
    if size in SIZE_CLASSES:
        return SIZE_CLASSES[size]
    half = _PAPER_SIDE // 2
    return (
        max(1, (_PAPER_MIN * size + half) // _PAPER_SIDE),
        max(1, (_PAPER_MAX * size + half) // _PAPER_SIDE),
    )


def map_size(shape: tuple[int, int]) -> int:
    """The size a map's class is decided by: its larger side."""
    return int(max(shape))


def size_config(size: int, **overrides: Any):
    """The :class:`~cpp_mujoco.grid.mdp.GridConfig` of a size class (``overrides``: other
    fields, e.g. ``fov_side``)."""
    low, high = budget_range(size)
    return GridConfig(min_budget=low, max_budget=high, **overrides)
