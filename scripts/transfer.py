"""Grid → MuJoCo transfer results: the grid-vs-physics table per map and the wind sweep.

Regenerates everything the README's transfer section shows:
    python scripts/transfer.py                  # full protocol in MuJoCo, sweep every 5th budget
    python scripts/transfer.py --budget-step 5  # quicker: every 5th budget everywhere
Writes out/transfer/{transfer.md, transfer.json, wind_sweep.png, coverage_*.png}.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from cpp_mujoco.demo import demo_policies, transfer_row  # noqa: E402
from cpp_mujoco.evaluate import atomic_write_text, evaluate  # noqa: E402
from cpp_mujoco.maps import bundled_maps  # noqa: E402
from cpp_mujoco.review.plots import coverage_figure  # noqa: E402
from cpp_mujoco.review.tables import format_table  # noqa: E402

WINDS = (0.0, 3.0, 6.0, 9.0)


def markdown(rows: list[dict]) -> str:
    columns = list(rows[0])
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(str(r[c]) for c in columns) + " |" for r in rows]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", nargs="+", default=bundled_maps())
    parser.add_argument("--budget-step", type=int, default=1, help="MuJoCo protocol budgets step")
    parser.add_argument("--sweep-step", type=int, default=5, help="wind sweep budgets step")
    parser.add_argument("--gust-std", type=float, default=1.0, help="gusts in the wind sweep")
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--out", default="out/transfer")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows, sweep = [], []
    for map_name in args.maps:
        name, policy = demo_policies(map_name)[0]  # the bundled agent where there is one
        budgets = list(range(25, 76, args.budget_step))
        grid = evaluate(policy, map_name, budgets=budgets, policy_name=name)
        physics = evaluate(policy, map_name, backend="mujoco", budgets=budgets,
                           policy_name=name, workers=args.workers, progress=True)  # fmt: skip
        rows.append(transfer_row(grid, physics))
        coverage_figure([grid, physics], out / f"coverage_{map_name}.png")
        sweep_budgets = list(range(25, 76, args.sweep_step))
        for wind in WINDS:
            result = evaluate(
                policy, map_name, backend="mujoco", budgets=sweep_budgets, policy_name=name,
                workers=args.workers, progress=True,
                env_kwargs={"wind_speed": wind, "gust_std": args.gust_std if wind else 0.0},
            )  # fmt: skip
            s = result.summary()
            sweep.append({"map": map_name, "policy": name, "wind m/s": wind,
                          "landing": f"{s['landing_ratio']:.2%}",
                          "coverage": f"{s['coverage_ratio']:.2%}",
                          "J/action": f"{s['energy_per_action_j']:.0f}",
                          "crashes": s["crashes"], "nfz viol.": s["nfz_violations"],
                          "_landing": s["landing_ratio"],
                          "_coverage": s["coverage_ratio"]})  # fmt: skip
    shown = [{k: v for k, v in r.items() if not k.startswith("_")} for r in sweep]
    print(format_table(rows, list(rows[0])))
    print()
    print(format_table(shown, list(shown[0])))
    atomic_write_text(
        out / "transfer.json", json.dumps({"transfer": rows, "wind": shown}, indent=2)
    )
    atomic_write_text(out / "transfer.md", markdown(rows) + "\n\n" + markdown(shown) + "\n")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for map_name in args.maps:
        entries = [r for r in sweep if r["map"] == map_name]
        winds = [r["wind m/s"] for r in entries]
        axes[0].plot(winds, [r["_landing"] for r in entries], "o-", label=f"map {map_name}")
        axes[1].plot(winds, [r["_coverage"] for r in entries], "o-", label=f"map {map_name}")
    for ax, label in zip(axes, ("landing ratio", "coverage ratio"), strict=True):
        ax.set_xlabel(f"steady wind, m/s (gusts σ = {args.gust_std:.1f} m/s)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle("Grid-trained agents in MuJoCo under wind")
    fig.savefig(out / "wind_sweep.png", dpi=120, bbox_inches="tight")
    print(f"\nwritten: {out}/transfer.md, transfer.json, wind_sweep.png, coverage_*.png")


if __name__ == "__main__":
    main()
