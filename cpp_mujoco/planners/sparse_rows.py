"""Linear rows gathered as triplets and built into one sparse matrix: how the exact planner's
model (:mod:`.optimal_model`) writes its constraints, many rows at a time."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix


@dataclass
class Rows:
    """Linear rows ``lo ≤ A·x ≤ hi`` gathered as triplets, then one sparse matrix."""

    rows: list
    cols: list
    vals: list
    lo: list
    hi: list

    @classmethod
    def empty(cls) -> Rows:
        return cls([], [], [], [], [])

    def add(self, cols: np.ndarray, vals: np.ndarray, lo: float, hi: float, count: int = 1,
            row_of: np.ndarray | None = None) -> None:  # fmt: skip
        """``count`` rows at once: entry k goes to new row ``row_of[k]`` (default: all to one)."""
        first = len(self.lo)
        row_of = np.zeros(len(cols), np.int64) if row_of is None else row_of
        self.rows.append(first + np.asarray(row_of, np.int64))
        self.cols.append(np.asarray(cols, np.int64))
        self.vals.append(np.asarray(vals, np.float64))
        self.lo.extend([lo] * count)
        self.hi.extend([hi] * count)

    def matrix(self, num_vars: int) -> csr_matrix:
        rows = np.concatenate(self.rows) if self.rows else np.zeros(0, np.int64)
        cols = np.concatenate(self.cols) if self.cols else np.zeros(0, np.int64)
        vals = np.concatenate(self.vals) if self.vals else np.zeros(0)
        out = csr_matrix((vals, (rows, cols)), shape=(len(self.lo), num_vars))
        out.sum_duplicates()
        return out
