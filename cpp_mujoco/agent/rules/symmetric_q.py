"""Symmetric Q as a rule: the action the Q-values averaged over the map's images rank first.

The grid MDP has no preferred direction, so the mean of the network's Q-values read on the 8
rotations and mirror images of a state (:func:`~cpp_mujoco.grid.symmetry.symmetric_q_values`)
is an estimate of Q that is itself symmetric. As the last rule it narrows each row to that
mean's argmax among the actions the rules before it allow, so the agent takes it.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import torch

from cpp_mujoco.agent.ddqn import mask_unsafe
from cpp_mujoco.agent.rules.base import Observation, QValues, Stateless
from cpp_mujoco.grid.symmetry import SYMMETRIC_Q_RULE, symmetric_q_values


class SymmetricQ(Stateless):
    """The argmax of the Q-values averaged over the map's images (a soft rule, put last)."""

    name: ClassVar[str] = "symmetric-q"
    rule: ClassVar[str] = SYMMETRIC_Q_RULE
    hard: ClassVar[bool] = False

    def allowed(
        self, obs: Observation, allowed: np.ndarray, floor: np.ndarray, q_values: QValues
    ) -> np.ndarray:
        q = torch.from_numpy(np.ascontiguousarray(symmetric_q_values(q_values, obs)))
        best = mask_unsafe(q, torch.from_numpy(allowed)).argmax(dim=1).numpy()
        out = np.zeros_like(allowed)
        out[np.arange(len(best)), best] = True
        return out

    def identity(self) -> dict[str, Any]:
        return {"symmetric_q": self.rule}
