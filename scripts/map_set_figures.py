"""Figures of map-set results already written: per-map coverage and example trajectories.

    python scripts/map_set_figures.py RESULT.json [MORE.json] [--out DIR] [--reference POLICY]
        [--maps gen16-s1000003 ...] [--count 4] [--merge]

``cpp-mujoco evaluate --map-set`` writes these figures beside its JSON itself; this redraws them
from JSON files alone — a run made on another machine (a GPU run of the general agent), other
sorting or other maps — without flying anything. Several results (e.g. ``heldout16-v1`` and
``heldout32-v1``) share one coverage figure, a panel per set; each gets its own trajectories.
``--merge``: the files are one set flown in separate runs (planners here, an agent elsewhere),
drawn as one result — same set, maps, backend and budgets, no policy twice — and written beside
the figures as ``A+B.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cpp_mujoco.review.map_set_figures import (
    MapSetFigureOptions,
    load_map_set_result,
    merge_map_set_results,
    write_map_set_figures,
)
from cpp_mujoco.util.io import atomic_write_text


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("results", nargs="+", type=Path, help="map-set result JSON files")
    p.add_argument("--out", type=Path, help="folder for the figures (default: the first JSON's)")
    p.add_argument("--reference", help="policy the maps are sorted by (default: the first)")
    p.add_argument("--maps", nargs="*", default=[], help="maps to draw trajectories on")
    p.add_argument("--count", type=int, default=4, help="else the first N maps (default: 4)")
    p.add_argument("--merge", action="store_true", help="the files are one set's separate runs")
    args = p.parse_args(argv)
    try:
        results = {path.stem: load_map_set_result(path) for path in args.results}
        if len(results) != len(args.results):
            raise ValueError("two results with the same file name; rename one")
        if args.merge:
            merged = merge_map_set_results(list(results.values()))
            results = {"+".join(results): merged}
            out = args.out or args.results[0].parent
            Path(out).mkdir(parents=True, exist_ok=True)
            atomic_write_text(
                Path(out) / f"{next(iter(results))}.json", json.dumps(merged, indent=2)
            )
        options = MapSetFigureOptions(args.reference, tuple(args.maps), max(1, args.count))
        out = args.out or args.results[0].parent
        paths = write_map_set_figures(results, out, options=options)
    except (ValueError, OSError) as e:
        print(f"map_set_figures.py: error: {e}", file=sys.stderr)
        return 2
    for stem, data in results.items():
        if not all("example" in r for r in data["rows"]):
            print(f"{stem}: no example episodes recorded, so no trajectories", file=sys.stderr)
    print("\n".join(str(path) for path in paths))
    return 0


if __name__ == "__main__":
    sys.exit(main())
