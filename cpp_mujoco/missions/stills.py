"""Two stills of a mission for the docs: the chase view with its HUD at the start and the end.

Regenerate them (1 to 2.5 min on 2 shared cores)::

    python -m cpp_mujoco.missions.stills            # docs/mission_A_start.png, mission_A_end.png
    python -m cpp_mujoco.missions.stills out/ B     # another folder, another map

The mission is the demo's (:func:`cpp_mujoco.missions.demo.run_demo`): the map's first demo policy
(its
bundled agent where it has one), from the middle landing cell, budget 50. The frames are exactly
what the chase video shows (the end one with the outcome banner), not decoded from the video.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image

from cpp_mujoco.maps import load_map
from cpp_mujoco.missions.lineup import demo_policies
from cpp_mujoco.missions.mission import fly_mission
from cpp_mujoco.physics.view.rendering import configure_gl
from cpp_mujoco.util.io import atomic_path

MAX_BYTES = 300_000  # a still in the docs stays small


def _save_png(frame: np.ndarray, path: Path) -> Path:
    """Lossless PNG; a 256-colour palette if that would be too large (flat colours keep)."""
    image = Image.fromarray(frame)
    with atomic_path(path) as tmp:
        image.save(tmp, format="PNG", optimize=True)
        if Path(tmp).stat().st_size > MAX_BYTES:
            image.quantize(256).save(tmp, format="PNG", optimize=True)
    return path


def mission_stills(
    out: str | Path = "docs", map_name: str = "A", budget: int = 50
) -> tuple[Path, Path]:
    """Fly the demo's mission on ``map_name``; write ``mission_<map>_start.png`` and
    ``mission_<map>_end.png`` (chase view, HUD) under ``out``; return their paths."""
    configure_gl()
    grid_map = load_map(map_name)
    _, policy = demo_policies(grid_map)[0]
    landing = np.argwhere(grid_map.landing)
    start = tuple(int(v) for v in landing[len(landing) // 2])
    frames: dict[str, np.ndarray] = {}

    def keep(frame: np.ndarray) -> None:
        frames.setdefault("start", frame)
        frames["end"] = frame  # the last one: the final state and the outcome

    fly_mission(policy, grid_map, budget=budget, start=start, on_chase_frame=keep)
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    stem = f"mission_{grid_map.name}"
    return (
        _save_png(frames["start"], folder / f"{stem}_start.png"),
        _save_png(frames["end"], folder / f"{stem}_end.png"),
    )


if __name__ == "__main__":
    args = sys.argv[1:]
    for written in mission_stills(*args[:2]):
        print(f"wrote {written} ({written.stat().st_size / 1000:.0f} KB)")
