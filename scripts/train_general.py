"""Train the bundled general agent (``load_agent("general")``) with the project's command, in
three stages, and check it on its validation maps.

    python scripts/train_general.py --out runs/general [--install] [-- more train-general options]

Stage 1 (:data:`STAGES`, ``OUT/stage1``) learns to fly generated 16×16 and 32×32 maps without
the return mask, guided by the safe greedy planner and taught by beam-search demonstrations: the
first 25,000 updates of a 200,000-update schedule. Stage 2 (``OUT/stage2``) starts from its
``agent.pt`` with the return mask on (every calm episode lands; the network learns where to
fly) for 36,000 updates. Stage 3 (``OUT/stage3``) starts from stage 2's ``best.pt`` with the
moves to new targets as an input (zero weights at first), 8,192 generated maps per size and the
paper's maps A, B and C in the pool (15 % of the episodes), for 36,000 updates at half the
learning rate; its ``best.pt`` (chosen on the validation maps) is the agent.
``--install`` copies it to ``cpp_mujoco/agent/bundled/general.pt`` (weights + metadata only).
Run again, the script resumes a stage whose folder holds a ``checkpoint.pt`` and skips a
finished one (docs/agent.md, "One agent for any map").
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

from cpp_mujoco.agent import BUNDLED_DIR, GENERAL_AGENT, load_agent
from cpp_mujoco.agent.general_eval import validate
from cpp_mujoco.agent.map_pool import VALIDATION_SEEDS, MapPool
from cpp_mujoco.cli import main as cli_main  # the `cpp-mujoco` command itself
from cpp_mujoco.io import atomic_write_bytes, atomic_write_text

STAGES = [  # (folder, train-general options)
    ("stage1", [
        "--no-return-mask", "--guide-updates", "200000", "--eval-every", "5000",
        "--stop-after-updates", "25000",
    ]),
    ("stage2", [
        "--init-from", "{stage1}/agent.pt", "--guide-updates", "200000",
        "--total-updates", "36000", "--eval-every", "4000",
    ]),
    ("stage3", [
        "--init-from", "{stage2}/best.pt", "--target-input", "--named-maps", "A", "B", "C",
        "--named-share", "0.15", "--maps-per-size", "8192", "--learning-rate", "0.00025",
        "--guide-updates", "200000", "--total-updates", "36000", "--eval-every", "4000",
        "--val-maps-per-size", "8",
    ]),
]  # fmt: skip


def stage_commands(out: Path, extra: list[str]) -> list[tuple[Path, list[str]]]:
    """(folder, ``cpp-mujoco`` argv) of each stage in ``out``, in order."""
    names = {folder: str(out / folder) for folder, _ in STAGES}
    runs = []
    for folder, options in STAGES:
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
    p.add_argument("extra", nargs="*", help="further train-general options, after --")
    args = p.parse_args(argv)
    out, t0 = Path(args.out), time.time()
    runs = stage_commands(out, args.extra)
    for folder, cmd in runs:
        if (folder / "checkpoint.pt").exists():
            if folder != runs[-1][0] and (folder / "final_eval.json").exists():
                continue  # a finished first stage: its agent.pt is the next start
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
    result = validate(agent, MapPool.generate((16, 32), 8, VALIDATION_SEEDS.start), 5)
    summary = {
        "commands": ["cpp-mujoco " + shlex.join(cmd) for _, cmd in runs],
        "agent": str(kept),
        "wall_s": round(time.time() - t0, 1),
        "validation": result.summary(),
    }
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2))
    print(json.dumps(summary["validation"]))
    if args.install:
        atomic_write_bytes(BUNDLED_DIR / f"{GENERAL_AGENT}.pt", kept.read_bytes())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
