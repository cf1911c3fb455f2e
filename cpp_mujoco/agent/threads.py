"""Torch CPU threads for training: a fixed count, or the faster of 1 and all cores, re-measured."""

from __future__ import annotations

import os

import numpy as np
import torch


def set_threads(threads: int) -> int:
    """Use ``threads`` torch threads (0 = all cores); returns the count set."""
    n = threads or os.cpu_count() or 1
    torch.set_num_threads(n)
    return n


class ThreadTuner:
    """``threads = 0``: pick the faster torch thread count while training (the CPU is shared).

    Measured on the 2-core machine: one update takes 29 ms with 2 threads vs 56 ms with 1 when the
    machine is idle, but 1,660 ms vs 190 ms when another process holds a core (OpenMP threads
    spin-wait on each other). Every ``period`` updates, ``probe`` updates run with each candidate
    count and the faster one is kept until the next probe.
    """

    def __init__(self, candidates: tuple[int, ...], period: int = 250, probe: int = 4):
        self.candidates, self.period, self.probe = candidates, period, probe
        self.times: dict[int, list[float]] = {n: [] for n in candidates}
        self.chosen = candidates[-1]

    def before(self, update: int) -> None:
        phase = update % self.period
        k = phase // self.probe
        torch.set_num_threads(self.candidates[k] if k < len(self.candidates) else self.chosen)

    def after(self, update: int, seconds: float) -> None:
        phase = update % self.period
        k = phase // self.probe
        if k < len(self.candidates):
            self.times[self.candidates[k]].append(seconds)
        if phase == self.probe * len(self.candidates) - 1:
            # skip the first probe update of each count (it pays the switch)
            self.chosen = min(
                self.candidates, key=lambda n: np.median(self.times[n][1:] or [np.inf])
            )
            self.times = {n: [] for n in self.candidates}
