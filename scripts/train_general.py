"""Train the bundled general agent (``load_agent("general")``) with the project's command, in
four stages, and check it on its validation maps.

    python scripts/train_general.py --out runs/general [--install] [-- more train-general options]
    python scripts/train_general.py --out runs/general --city --install   # general-city

Stage 1 (:data:`STAGES`, ``OUT/stage1``) learns to fly generated 16×16 and 32×32 maps without
the return mask, guided by the safe greedy planner and taught by beam-search demonstrations: the
first 25,000 updates of a 200,000-update schedule. Stage 2 (``OUT/stage2``) starts from its
``agent.pt`` with the return mask on (every calm episode lands; the network learns where to
fly) for 36,000 updates. Stage 3 (``OUT/stage3``) starts from stage 2's ``best.pt`` with the
moves to new targets as an input (zero weights at first), 8,192 generated maps per size and the
paper's maps A, B and C in the pool (15 % of the episodes), for 36,000 updates at half the
learning rate. Stage 4 (``OUT/stage4``) starts from stage 3's ``best.pt`` with A, B and C in 30 %
of the episodes, their demonstrations at every budget of the protocol and 40 % of each
demonstration minibatch drawn from them, at 1e-4, for 12,000 updates; its ``best.pt`` (chosen on
the validation maps) is the agent. ``--install`` copies it to
``cpp_mujoco/agent/bundled/general.pt`` (weights + metadata only) with the progress mask added to
its rules (:data:`INSTALL_RULES`).
``--wind`` replaces stage 4 by ``OUT/stage4-wind``: stage 3's ``best.pt`` fine-tuned in the grid's
wind option (0–12 m/s, 35 % calm, the wind inputs starting at zero weight, the return mask priced
at the observed wind), guided by ``safe-greedy-wind`` and taught by ``beam-search-wind`` on the
16×16 maps (the wind planners take minutes a 32×32 map) for 12,000 updates; its ``best.pt``
(chosen on landing in wind) is ``general-wind`` (``--install`` copies it to ``general-wind.pt``).
``--city`` adds ``OUT/stage5-city`` after stage 4: its ``best.pt`` fine-tuned on city maps
(buildings that hide targets, the obstacle layer as an input at zero weight to start, 8,192 city
maps per size) at 1e-4 for 12,000 updates; its ``best.pt`` (chosen on the city validation maps)
is ``general-city`` (``--install`` copies it to ``general-city.pt`` with the progress mask and
the symmetric-Q rule added to its rules, :data:`INSTALL_RULES`).
Run again, the script resumes a stage whose folder holds a ``checkpoint.pt`` and skips a
finished one (docs/agent.md, "The general agent").
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

from cpp_mujoco.agent import (
    BUNDLED_DIR,
    GENERAL_AGENT,
    GENERAL_CITY_AGENT,
    GENERAL_WIND_AGENT,
    load_agent,
)
from cpp_mujoco.agent.checkpoint import atomic_save, load_checkpoint
from cpp_mujoco.agent.general_eval import validate
from cpp_mujoco.agent.map_pool import VALIDATION_SEEDS, MapPool
from cpp_mujoco.agent.rules import RULE_FLAGS, check_rule_names, rule_names_of
from cpp_mujoco.cli.main import main as cli_main
from cpp_mujoco.grid.wind import GridWind  # the `cpp-mujoco` command itself
from cpp_mujoco.util.io import atomic_write_text

# rules the installed file acts with beside its stage's own: both take only moves nearer a target
# while one is in reach; the city agent also the argmax of its Q-values averaged over the map's 8
# rotations and mirror images (held-out sets and city32-v1: docs/agent.md)
INSTALL_RULES = {
    GENERAL_AGENT: ("progress-mask",),
    GENERAL_CITY_AGENT: ("progress-mask", "symmetric-q"),
}

BASE_STAGES = [  # (folder, train-general options): stages 1-3, which the calm and wind agents share
    ("stage1", [
        "--no-return-mask", "--set", "guide_updates=200000", "--eval-every", "5000",
        "--stop-after-updates", "25000",
    ]),
    ("stage2", [
        "--init-from", "{stage1}/agent.pt", "--set", "guide_updates=200000",
        "--total-updates", "36000", "--eval-every", "4000",
    ]),
    ("stage3", [
        "--init-from", "{stage2}/best.pt", "--target-input", "--named-maps", "A", "B", "C",
        "--set", "named_share=0.15", "--maps-per-size", "8192", "--learning-rate", "0.00025",
        "--set", "guide_updates=200000", "--total-updates", "36000", "--eval-every", "4000",
        "--set", "val_maps_per_size=8",
    ]),
]  # fmt: skip
CALM_STAGE = ("stage4", [
    "--init-from", "{stage3}/best.pt", "--target-input", "--named-maps", "A", "B", "C",
    "--set", "named_share=0.3", "--set", "named_demo_budget_step=1",
    "--set", "named_demo_share=0.4",
    "--maps-per-size", "8192", "--set", "demo_maps_per_size=32", "--learning-rate", "0.0001",
    "--set", "guide_updates=200000", "--total-updates", "12000", "--eval-every", "3000",
    "--set", "val_maps_per_size=8", "--set", "checkpoint_every=1500",
])  # fmt: skip
STAGES = [*BASE_STAGES, CALM_STAGE]


WIND_STAGE = ("stage4-wind", [
    "--init-from", "{stage3}/best.pt", "--target-input", "--named-maps", "A", "B", "C",
    "--set", "named_share=0.15", "--maps-per-size", "8192", "--set", "val_maps_per_size=8",
    "--learning-rate", "0.00015", "--set", "guide_fraction=0.25", "--set", "guide_updates=12000",
    "--total-updates", "12000", "--eval-every", "2000", "--set", "checkpoint_every=1000",
    "--wind-max-speed", "12", "--set", "wind_calm_fraction=0.35", "--set", "guide=safe-greedy-wind",
    "--set", "demo_planner=beam-search-wind", "--set", "demo_max_side=16",
    "--set", "wind_planner_sigmas=4.0",
    "--set", "best_by=landing", "--set", "final_eval=false",
])  # fmt: skip
CITY_STAGE = ("stage5-city", [
    "--init-from", "{stage4}/best.pt", "--target-input", "--set", "obstacle_input=true",
    "--set", "map_family=city", "--maps-per-size", "8192", "--set", "demo_maps_per_size=32",
    "--learning-rate", "0.0001", "--set", "guide_updates=200000", "--total-updates", "12000",
    "--eval-every", "3000", "--set", "val_maps_per_size=8", "--set", "checkpoint_every=1500",
])  # fmt: skip
WIND_VALIDATION = GridWind(max_speed=12.0, calm_fraction=0.35)  # the stage's own wind option


def stage_commands(
    out: Path, extra: list[str], wind: bool = False, city: bool = False
) -> list[tuple[Path, list[str]]]:
    """(folder, ``cpp-mujoco`` argv) of each stage in ``out``, in order (``wind``: the wind stage
    in place of stage 4; ``city``: the city stage after it)."""
    if wind and city:
        raise ValueError("--wind and --city train two different agents: give one")
    stages = [*BASE_STAGES, WIND_STAGE] if wind else [*STAGES, CITY_STAGE] if city else STAGES
    names = {folder: str(out / folder) for folder, _ in stages}
    runs = []
    for folder, options in stages:
        argv = ["train-general", "--out", str(out / folder), "--threads", "1", "--no-progress"]
        runs.append((out / folder, argv + [o.format(**names) for o in options] + extra))
    return runs


def _run(argv: list[str]) -> int:
    try:
        return cli_main(argv)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 2


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--out", default="runs/general", help="one run folder per stage in here")
    p.add_argument("--install", action="store_true", help="copy best.pt into the package")
    p.add_argument("--wind", action="store_true", help="the wind stage in place of stage 4")
    p.add_argument("--city", action="store_true", help="the city stage after stage 4")
    p.add_argument("extra", nargs="*", help="further train-general options, after --")
    args = p.parse_args(argv)
    out, t0 = Path(args.out), time.time()
    try:
        runs = stage_commands(out, args.extra, args.wind, args.city)
    except ValueError as e:
        p.error(str(e))
    for folder, cmd in runs:
        if (folder / "checkpoint.pt").exists():
            if folder != runs[-1][0] and (folder / "final_eval.json").exists():
                continue  # a finished earlier stage: its weights start the next
            cmd = [*cmd, "--resume"]
        code = _run(cmd)
        if code != 0:
            again = shlex.join(["python", "scripts/train_general.py", *(argv or sys.argv[1:])])
            print(
                f"train_general: {folder} stopped (exit {code}); run again to resume: {again}",
                file=sys.stderr,
            )
            return code
    kept = runs[-1][0] / "best.pt"
    agent = load_agent(kept)
    pool = MapPool.generate(
        (16, 32), 8, VALIDATION_SEEDS.start, **({"family": "city"} if args.city else {})
    )
    if args.wind:  # the wind stage is judged in its own wind, its return rule with its margin
        pool = pool.flown_with(WIND_VALIDATION, agent.wind_margin)
    result = validate(agent, pool, 5)
    summary = {
        "commands": ["cpp-mujoco " + shlex.join(cmd) for _, cmd in runs],
        "agent": str(kept),
        "wall_s": round(time.time() - t0, 1),
        "validation": result.summary(),
    }
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2))
    print(json.dumps(summary["validation"]))
    if args.install:
        name = (
            GENERAL_WIND_AGENT if args.wind else GENERAL_CITY_AGENT if args.city else GENERAL_AGENT
        )
        install(kept, BUNDLED_DIR / f"{name}.pt", INSTALL_RULES.get(name, ()))
    return 0


def install(agent_file: Path, target: Path, extra_rules: tuple[str, ...] = ()) -> None:
    """Write the agent file ``agent_file`` to ``target`` acting also with ``extra_rules`` (its
    ``rules`` list and its config's rule flags both say so)."""
    obj = load_checkpoint(agent_file)
    names = check_rule_names([*rule_names_of(obj), *extra_rules])
    flags = {flag: rule in names for flag, rule in RULE_FLAGS.items()}
    atomic_save({**obj, "rules": names, "config": {**obj["config"], **flags}}, target)


if __name__ == "__main__":
    raise SystemExit(main())
