"""The ``maps`` subcommand's commands (``maps draw``, ``maps generate``, ``maps import``) and
``evaluate --map-set``'s, which flies a held-out map set; their parsers are in
:mod:`cpp_mujoco.cli.parsers`.
"""

from __future__ import annotations

import os
import sys
from contextlib import nullcontext
from pathlib import Path

from cpp_mujoco.cli.optimum import optimal_options
from cpp_mujoco.cli.options import check_agent_file, out_dir, progress_wanted, rules_for
from cpp_mujoco.grid.wind import GridWind
from cpp_mujoco.map_sets.generator import config_from_options, generate_from_seed
from cpp_mujoco.map_sets.sets import HELDOUT_SEEDS, load_map_set, map_set_spec
from cpp_mujoco.map_sets.size_classes import budget_range
from cpp_mujoco.maps import MAX_SIDE, GridMap, MapError, bundled_maps, load_map
from cpp_mujoco.maps.lineage import import_uavsim
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.map_sets import evaluate_map_set
from cpp_mujoco.review.map_set_figures import load_map_set_result, write_map_set_figures
from cpp_mujoco.review.plots import map_figure
from cpp_mujoco.review.results import file_part
from cpp_mujoco.util.io import is_path_like
from cpp_mujoco.util.tables import format_table


# -------------------------------------------------------------------------- maps generate
def _claim_folder(path: str, overwrite: bool) -> Path:
    """The output folder, created; a non-empty one only with ``overwrite``."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} is a file, not a folder")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise ValueError(f"--out {out} is not empty; give --overwrite to write into it anyway")
    out = out_dir(path)
    if not os.access(out, os.W_OK | os.X_OK):
        raise OSError(f"cannot write to output folder {out}: permission denied")
    return out


def cmd_generate(args) -> None:
    """``maps generate N``: N maps from seed ``--seed`` on, one line per map."""
    size, first = args.size, args.seed
    seeds = range(first, first + args.count)
    if size > MAX_SIDE:
        raise ValueError(f"--size {size}: maps are at most {MAX_SIDE} cells a side")
    options = {} if args.door_wall is None else {"door_wall": args.door_wall}
    if args.family != "paper":
        if options:
            raise ValueError(f"--door-wall is an option of the paper family, not {args.family}")
        options = {"family": args.family}
    config_from_options(**options)  # a bad option is an error before the folder
    out = _claim_folder(args.out, args.overwrite)
    if seeds.start < HELDOUT_SEEDS.stop and HELDOUT_SEEDS.start < seeds.stop:
        print(
            f"warning: seeds {HELDOUT_SEEDS.start}..{HELDOUT_SEEDS.stop - 1} make the held-out "
            "test maps; do not train on these",
            file=sys.stderr,
        )
    for seed in seeds:
        grid_map = generate_from_seed(seed, size, **options)
        path = out / f"{grid_map.name}.png"
        grid_map.save(path)
        c = grid_map.counts()
        yellow = int((grid_map.target & grid_map.nfz).sum())
        print(
            f"{grid_map.name}  {size}x{size}  landing {c['landing']}  target {c['target']} "
            f"({grid_map.target.mean():.0%})  no-fly {c['nfz']}  yellow {yellow}  "
            f"digest {grid_map.digest}  {path}"
        )
    low, high = budget_range(size)
    print(f"{len(seeds)} maps in {out}/ (size class {size}x{size}: budgets {low}..{high})")


# --------------------------------------------------------------------------- evaluate --map-set
def agent_entry(
    spec: str, agent, rules: list[str] | None, value_beam: int | None = None
) -> tuple[str, object]:
    """(label, agent) of ``--agent SPEC`` flown with ``--rule rules`` (None: the file's own
    rules) and, with ``--value-beam WIDTH`` or a spec ``NAME+value-beam``, through the beam search
    its Q-values rank; a label with other rules than the file's says which (so do file names:
    runs with other rules never overwrite each other), one with search says so and its width."""
    from cpp_mujoco.agent.value_beam import (  # heavy: torch, only with --agent
        DEFAULT_WIDTH,
        ValueBeamAgent,
        split_search,
    )

    name, search = split_search(spec)
    names = rules_for(agent.rule_names, rules)
    label = f"ddqn[{name}]"
    if names != agent.rule_names:
        label, agent = f"ddqn[{name}, rules: {'+'.join(names) or 'none'}]", agent.with_rules(names)
    width = value_beam or (DEFAULT_WIDTH if search else None)
    if width:
        agent = ValueBeamAgent(agent, width)
        label += agent.name.removeprefix(agent.agent.name)
    return label, agent


def _set_agent(spec: str, set_name: str, size: int):
    """A trained agent for a map set (``NAME+value-beam``: agent NAME, which will search): never
    a per-map agent (the bundled ones, or one trained on a bundled map), which only flies the
    map it was trained on."""
    from cpp_mujoco.agent import (  # heavy: torch, only with --agent
        GENERAL_AGENTS,
        bundled_agents,
        load_agent,
    )
    from cpp_mujoco.agent.value_beam import split_search  # heavy: torch, only with --agent

    spec = split_search(spec)[0]
    check_agent_file(spec)
    per_map = f"agent {spec!r} is a per-map agent"
    if not is_path_like(spec, ".pt") and spec in bundled_agents() and spec not in GENERAL_AGENTS:
        raise ValueError(
            f"{per_map}: it flies only map {spec.split('-')[0]}, not map set {set_name!r}; "
            "evaluate planners (--planner) or an agent trained on generated maps there"
        )
    agent = load_agent(spec)
    trained_on = agent.metadata.get("map")
    if trained_on in bundled_maps():
        raise ValueError(f"{per_map} (trained on map {trained_on}); it cannot fly {set_name!r}")
    if agent.map_shape is not None and tuple(agent.map_shape) != (size, size):
        h, w = agent.map_shape
        raise ValueError(
            f"agent {spec!r} flies {h}x{w} maps; map set {set_name!r} is {size}x{size}"
        )
    return agent


def grid_wind_option(args):
    """``--grid-wind S``: the grid's wind option at S m/s in every episode, each from one of the
    four compass directions, with the calibrated gusts (None without it)."""
    speed = getattr(args, "grid_wind", None)
    if speed is None:
        return None
    if args.backend != "grid":
        raise ValueError("--grid-wind is the grid's wind option; in MuJoCo use --wind-speed")
    return GridWind(min_speed=speed, max_speed=speed, calm_fraction=0.0)


def cmd_evaluate_map_set(
    args, planner_names: tuple[str, ...], weather: dict | None = None, runtime=None
) -> None:
    """``evaluate --map-set NAME``: the protocol on every map of the set (on the grid or in
    MuJoCo), a per-map table, the means per policy, one JSON with all of it, and its figures
    beside it — as ``evaluate`` writes figures beside its JSON for single maps."""
    if args.map:
        raise ValueError("--map-set replaces --map; give one of them")
    spec = map_set_spec(args.map_set)
    agents = [
        agent_entry(a, _set_agent(a, spec.name, spec.size), args.rule, args.value_beam)
        for a in args.agent
    ]
    maps = load_map_set(spec.name, first=args.first)
    names = args.planner or ([] if agents else list(planner_names))

    policies = [(n, make_planner(n, optimal=optimal_options(args))) for n in names] + agents
    out = out_dir(args.out)
    physics: dict = {"workers": args.workers}
    if args.backend == "mujoco":
        engine = "ray" if args.ray else "local"
        physics.update(env_kwargs=weather or {}, engine=engine)
    wind = grid_wind_option(args)
    if wind is not None:
        physics["grid_wind"] = wind
    part = "" if args.first is None else f"_first{args.first}"
    backend = args.backend if wind is None else f"grid-wind{args.grid_wind:g}"  # names the wind
    stem = f"{backend}_{file_part(spec.name)}{part}"
    checkpoint = Path(args.checkpoint or out / f"{stem}.rows.json")  # a stopped flight resumes
    if checkpoint.exists():
        print(f"resuming from {checkpoint} (the rows of this very flight it holds are reused)")
    with runtime or nullcontext():
        result = evaluate_map_set(
            spec, maps, policies, args.budget_step, progress_wanted(args), args.backend,
            checkpoint=checkpoint, **physics,
        )  # fmt: skip
    per_map, means = result.tables()
    path = result.to_json(out / f"{stem}.json")
    checkpoint.unlink()  # the result holds every row now
    grid_maps = {m.label: m for m in result.maps}  # drawn from the JSON just written
    figures = write_map_set_figures({path.stem: load_map_set_result(path)}, out, grid_maps)
    (flown,) = result.budgets.values()  # a set is one size class
    budgets = f"budgets {flown[0]}..{flown[-1]} step {args.budget_step}"
    where = args.backend if wind is None else f"grid, wind {args.grid_wind:g} m/s from N/E/S/W"
    print(f"map set {spec.name}: {len(maps)} of {spec.count} maps, {budgets}, {where}")
    print(per_map)
    print()
    print(means)
    print(f"\nresults: {path}")
    print("figures: " + ", ".join(str(f) for f in figures))


def cmd_draw(args) -> None:
    """``maps draw``: each map as the paper's colour figure, and its cell counts."""
    specs = getattr(args, "map", None) or bundled_maps()
    grid_maps = [load_map(s, getattr(args, "cell_pixels", None)) for s in specs]  # checked first
    out = out_dir(getattr(args, "out", None) or "out/maps")
    rows = []
    for grid_map in grid_maps:
        path = map_figure(grid_map, out / f"map_{file_part(grid_map.label)}.png")
        rows.append(
            {
                "map": grid_map.label,
                "size": "x".join(map(str, grid_map.shape)),
                **grid_map.counts(),
                "figure": str(path),
            }
        )
    print(format_table(rows, ["map", "size", "landing", "target", "nfz", "figure"]))


def _import_uavsim(args, source: Path, out: Path) -> tuple[GridMap, str]:
    """``--format uavsim``: the lineage's map and its targets, and a line on the targets."""
    if args.cell_pixels is not None or args.white_background:
        raise ValueError("--cell-pixels and --white-background are for --format ours")
    if args.seed is not None and args.target_fraction is None:
        raise ValueError("--seed seeds the drawn targets; give it with --target-fraction")
    seed = 0 if args.seed is None else args.seed
    read = import_uavsim(source, args.targets, args.target_fraction, seed, name=out.stem)
    return read.grid_map, read.describe()


def cmd_import(args) -> None:
    """``maps import``: a map drawn elsewhere (or a uavSim map: ``--format uavsim``), written in
    the map format (one pixel per cell, black empty) so that every command reads it as it is."""
    source, out = Path(args.source), Path(args.out)
    if out.exists() and not args.overwrite:
        raise ValueError(f"{out} exists; --overwrite replaces it")
    note = ""
    uavsim_only = {"--targets": args.targets, "--target-fraction": args.target_fraction}
    given = [
        flag for flag, value in {**uavsim_only, "--seed": args.seed}.items() if value is not None
    ]
    if args.format == "uavsim":
        grid_map, note = _import_uavsim(args, source, out)
    elif given:
        raise ValueError(f"{', '.join(given)}: only with --format uavsim")
    elif source.suffix.lower() == ".txt":
        try:
            text = source.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise MapError(f"{source} cannot be read as text ({exc})") from None
        grid_map = GridMap.from_ascii(text, name=out.stem)
    else:
        grid_map = load_map(source, args.cell_pixels, white_background=args.white_background)
    out.parent.mkdir(parents=True, exist_ok=True)
    grid_map.save(out)
    saved = load_map(out)  # read back as every command will
    counts = ", ".join(f"{k} {v}" for k, v in saved.counts().items())
    print(f"{out}: {saved.shape[0]}x{saved.shape[1]} cells ({counts}), digest {saved.digest}")
    if note:
        print(note)
