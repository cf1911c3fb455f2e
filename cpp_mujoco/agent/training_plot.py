"""A training run's log: ``log.csv`` (one row per evaluation) and ``training.png``, the paper's
Fig. 4 (greedy return, landing and coverage ratio over training). Both are written atomically.

The figure is drawn on a standalone ``matplotlib.figure.Figure`` (no pyplot, no global backend
switch): the trainer redraws it after every evaluation without touching the caller's matplotlib.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Sequence
from pathlib import Path

from matplotlib.figure import Figure

from cpp_mujoco.util.io import atomic_path, atomic_write_text

LOG_FIELDS = [
    "updates", "env_steps", "episodes", "wall_s", "eval_landing", "eval_coverage", "eval_return",
    "train_return", "train_landing", "train_coverage", "loss", "q", "updates_per_s",
    "env_steps_per_s",
]  # fmt: skip


def write_training_log(history: Sequence[dict], out: str | os.PathLike, title: str = "") -> None:
    """Rewrite ``out/log.csv`` and ``out/training.png`` from the whole ``history``."""
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, LOG_FIELDS)
    writer.writeheader()
    writer.writerows(history)
    atomic_write_text(Path(out) / "log.csv", text.getvalue())
    plot_history(history, Path(out) / "training.png", title=title)


def plot_history(history: Sequence[dict], path: str | os.PathLike, title: str = "") -> Path:
    """Write the figure of ``history`` (rows of ``log.csv``) to ``path`` atomically."""
    x = [h["episodes"] for h in history]
    fig = Figure(figsize=(7, 5.5))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(x, [h["eval_return"] for h in history], color="tab:blue", marker=".")
    ax1.set_ylabel("greedy return (mean)")
    ax1.grid(alpha=0.3)
    ax2.plot(x, [h["eval_landing"] for h in history], label="landing ratio", marker=".")
    ax2.plot(x, [h["eval_coverage"] for h in history], label="coverage ratio", marker=".")
    ax2.set_ylim(0, 1.02)
    ax2.set_xlabel("training episodes")
    ax2.legend(loc="lower right")
    ax2.grid(alpha=0.3)
    if title:
        ax1.set_title(title)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format=Path(path).suffix.lstrip(".") or "png")
    return Path(path)
