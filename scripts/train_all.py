"""Train the bundled agents for maps A, B, C with the project's training command, one after another.

    python scripts/train_all.py --out runs/bundled [--maps A B C] [--minutes 20] [--install]
    python scripts/train_all.py --wind --out runs/wind [--install]     # A-wind, B-wind, C-wind

``--wind`` trains the wind-robust agents in two runs per map (:data:`WIND_STAGES`,
``docs/agent.md``): ``OUT/M-stage1`` starts from the map's bundled paper agent and learns in the
grid's wind option, ``OUT/M`` continues from its final agent; on the maps of
:data:`PHYSICS_UPDATES` a third run, ``OUT/M-physics``, fine-tunes ``OUT/M/best.pt`` in MuJoCo.
``--install`` then writes ``M-wind.pt`` from the last run: ``best.pt`` of a grid run, ``agent.pt``
of the physics run (its ``best.pt`` is chosen on the grid, which is not what it was tuned for).

Each map runs ``cpp-mujoco train --map M --seed 0 --out OUT/M --max-minutes MIN`` (through the same
argparse handler), then evaluates ``best.pt`` on the full protocol; ``--install`` copies it to
``cpp_mujoco/agent/bundled/M.pt`` (weights + metadata only). The script stops at the first map
whose training fails, is refused or is interrupted, and prints how to go on; run again, it resumes
every run folder that holds a ``checkpoint.pt``.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

from cpp_mujoco.agent import BUNDLED_DIR, load_agent
from cpp_mujoco.cli.main import main as train_main  # the `cpp-mujoco` command itself
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.util.io import atomic_write_bytes, atomic_write_text

# the wind-robust agents' training, two runs per map (docs/agent.md): fine-tune the paper agent
# in winds of 0..12 m/s (20 % calm), guided by and learning from planners that price moves with
# the wind; then continue from its final agent with more calm air, a lower learning rate and
# best.pt chosen by landings
WIND_STAGES = [  # (folder suffix, seed offset, options)
    ("stage1", 0, [
        "--wind-max-speed", "12", "--set", "guide=safe-greedy-wind",
        "--set", "demo_planner=beam-search-wind", "--learning-rate", "0.00025",
        "--total-updates", "10000", "--init-from", "{paper}",
    ]),
    ("", 1, [
        "--wind-max-speed", "12", "--set", "wind_calm_fraction=0.35",
        "--set", "guide=safe-greedy-wind",
        "--set", "demo_planner=beam-search-wind", "--learning-rate", "0.00015",
        "--total-updates", "6000", "--set", "best_by=landing", "--init-from", "{stage1}/agent.pt",
        "--set", "wind_planner_sigmas={sigmas}",
    ]),
]  # fmt: skip
# per map, from stage 2 on: the margin the wind planners keep as guide and demonstrator (the
# agent learns the margin its teachers keep) and the physics run's calm share. 4σ lands A and C
# ≥ 99.5 % at the rated wind; B's gust peaks take 6σ; half the slots calm kept B's and C's calm
# landings at 100 % where a fifth or a third did not always (CHANGELOG.md, the training record)
WIND_MARGIN = {"A": ("4.0", "0.2"), "B": ("6.0", "0.5"), "C": ("4.0", "0.5")}
# then the grid agent fine-tuned in MuJoCo (the updates each bundled agent had): the map's calm
# share of the 64 slots calm, the rest at the rated wind from N/E/S/W; a small learning rate and
# the grid demonstrations in every minibatch keep the grid agent. It removes the calm-air
# transfer crashes that grid training leaves (docs/agent.md, "Fine-tuning in physics")
PHYSICS_UPDATES = {"A": 2000, "B": 3000, "C": 2000}
PHYSICS_STAGE = ("physics", 0, [
    "--backend", "mujoco", "--init-from", "{stage2}/best.pt", "--wind-max-speed", "12",
    "--set", "wind_calm_fraction=0.35", "--set", "physics_wind_speed=9", "--set",
    "physics_calm_share={calm_share}", "--set", "guide_fraction=0", "--set", "demo_fraction=0.25",
    "--set", "demo_planner=beam-search-wind", "--set", "wind_planner_sigmas={sigmas}",
    "--learning-rate", "2e-5", "--set", "best_by=landing", "--num-envs", "64",
    "--set", "updates_per_step=2", "--total-updates", "{physics_updates}",
])  # fmt: skip


def wind_runs(m: str, out: Path) -> list[tuple[Path, int, list[str]]]:
    """Map ``m``'s wind runs in ``out``: (folder, seed offset, ``train`` options), in order."""
    stage = {
        "paper": m,
        "stage1": str(out / f"{m}-stage1"),
        "stage2": str(out / m),
        "physics_updates": PHYSICS_UPDATES.get(m),
    }
    stage["sigmas"], stage["calm_share"] = WIND_MARGIN.get(m, ("4.0", "0.2"))
    stages = WIND_STAGES + ([PHYSICS_STAGE] if m in PHYSICS_UPDATES else [])
    return [
        (out / (f"{m}-{suffix}" if suffix else m), offset, [o.format(**stage) for o in options])
        for suffix, offset, options in stages
    ]


def _train(cmd: list[str]) -> int:
    """``cpp-mujoco train`` in this process; its exit status (argparse errors exit 2)."""
    try:
        return train_main(cmd)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 2


def _stopped(m: str, out: Path, code: int, argv: list[str] | None) -> str:
    """Why the script stops at map ``m`` and how to go on; maps after it did not run."""
    again = shlex.join(
        ["python", "scripts/train_all.py", *(sys.argv[1:] if argv is None else argv)]
    )
    if code in (130, 143):
        return (
            f"train_all: map {m} stopped by {'SIGINT' if code == 130 else 'SIGTERM'} after saving "
            f"{out / 'checkpoint.pt'}; resume it (and the maps after it) with: {again}"
        )
    return (
        f"train_all: training map {m} failed (exit {code}, error above); the maps after it did "
        f"not run and summary.json is unchanged. Fix the cause, then run again: {again} "
        "(run folders holding a checkpoint.pt are resumed; for a non-empty folder without one "
        "give another --out or add -- --overwrite)"
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--out", default="runs/bundled", help="one run folder per map in here")
    p.add_argument("--maps", nargs="+", default=["A", "B", "C"], help="bundled maps")
    p.add_argument("--seed", type=int, default=0, help="training seed")
    p.add_argument("--minutes", type=float, default=None, help="minutes per map (20; --wind: 0)")
    p.add_argument("--wind", action="store_true", help="train the wind-robust agents M-wind")
    p.add_argument("--install", action="store_true", help="copy best.pt into the package")
    p.add_argument("extra", nargs="*", help="further train options, after --")
    args = p.parse_args(argv)
    summary = {}
    minutes = args.minutes if args.minutes is not None else (0.0 if args.wind else 20.0)
    for m in args.maps:
        t0 = time.time()
        # (folder, seed offset, options); the last is kept
        runs = wind_runs(m, Path(args.out)) if args.wind else [(Path(args.out) / m, 0, [])]
        out = runs[-1][0]
        # a physics run's best.pt is chosen on the grid, not what it was tuned for: keep its last
        kept = out / ("agent.pt" if args.wind and m in PHYSICS_UPDATES else "best.pt")
        for folder, offset, options in runs:
            seed = str(args.seed + offset)
            cmd = ["train", "--map", m, "--seed", seed, "--out", str(folder), *options]
            cmd += ["--max-minutes", str(minutes), "--no-progress", *args.extra]
            if (folder / "checkpoint.pt").exists() and "--overwrite" not in args.extra:
                if folder != out and (folder / "final_eval.json").exists():
                    continue  # an earlier stage that finished: its agent.pt is the next start
                cmd.append("--resume")
            code = _train(cmd)
            if code != 0:  # a refused folder or a bad option must not fall through to a stale best
                print(_stopped(m, folder, code, argv), file=sys.stderr)
                return code
        if not kept.is_file():  # no evaluation ran: nothing was selected
            print(
                f"train_all: {kept} is missing: the run ended before its first "
                "evaluation; give more --minutes (or -- --eval-every N with a smaller N)",
                file=sys.stderr,
            )
            return 1
        res = evaluate(load_agent(kept), m)
        summary[m] = {
            "command": "cpp-mujoco " + " ".join(cmd),  # the last run's
            "agent": str(kept),
            "wall_s": round(time.time() - t0, 1),
            "evaluated_on": "the full protocol on the grid, calm air (the paper's MDP)",
            "landing_ratio": res.landing_ratio,
            "coverage_ratio": res.coverage_ratio,
        }
        print(json.dumps({m: summary[m]}), flush=True)
        if args.install:
            name = f"{m}-wind" if args.wind else m
            atomic_write_bytes(BUNDLED_DIR / f"{name}.pt", kept.read_bytes())
    atomic_write_text(Path(args.out) / "summary.json", json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
