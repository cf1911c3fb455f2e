"""Train the bundled agents for maps A, B, C with the project's training command, one after another.

    python scripts/train_all.py --out runs/bundled [--maps A B C] [--minutes 20] [--install]

Each map runs ``cpp-mujoco train --map M --seed 0 --out OUT/M --max-minutes MIN`` (through the same
argparse handler), then evaluates ``best.pt`` on the full protocol; ``--install`` copies it to
``cpp_mujoco/agent/bundled/M.pt`` (weights + metadata only).
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

from cpp_mujoco.agent import BUNDLED_DIR, load_agent
from cpp_mujoco.agent.cli import main as train_main
from cpp_mujoco.evaluate import evaluate


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--out", default="runs/bundled")
    p.add_argument("--maps", nargs="+", default=["A", "B", "C"])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--minutes", type=float, default=20.0)
    p.add_argument("--install", action="store_true", help="copy best.pt into the package")
    p.add_argument("extra", nargs="*", help="further train options, after --")
    args = p.parse_args(argv)
    summary = {}
    for m in args.maps:
        out = Path(args.out) / m
        cmd = ["train", "--map", m, "--seed", str(args.seed), "--out", str(out)]
        cmd += ["--max-minutes", str(args.minutes), "--no-progress", *args.extra]
        if (out / "checkpoint.pt").exists():
            cmd.append("--resume")
        t0 = time.time()
        train_main(cmd)
        res = evaluate(load_agent(out / "best.pt"), m)
        summary[m] = {
            "command": "cpp-mujoco " + " ".join(cmd),
            "wall_s": round(time.time() - t0, 1),
            "landing_ratio": res.landing_ratio,
            "coverage_ratio": res.coverage_ratio,
        }
        print(json.dumps({m: summary[m]}), flush=True)
        if args.install:
            shutil.copyfile(out / "best.pt", BUNDLED_DIR / f"{m}.pt")
    (Path(args.out) / "summary.json").write_text(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
