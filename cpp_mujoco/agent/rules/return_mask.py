"""The return mask as a rule: only the actions after which the way home is still paid.

The rule itself is the grid's (:func:`~cpp_mujoco.grid.return_rule.paid_actions`, read from an
observation by :func:`~cpp_mujoco.agent.home_input.safe_actions`); in an observed wind it keeps
the wind planners' ``margin``. It is the one hard rule: training uses it too (the soft-max and
the DDQN target of an agent trained with it), so an agent file that says so flies with it.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from cpp_mujoco.agent.home_input import safe_actions
from cpp_mujoco.agent.rules.base import Observation, QValues, Stateless
from cpp_mujoco.grid.return_rule import RETURN_RULE
from cpp_mujoco.grid.way_home import ReturnMargin


class ReturnMask(Stateless):
    """Only the actions that keep the way home paid (a hard rule)."""

    name: ClassVar[str] = "return-mask"
    rule: ClassVar[str] = RETURN_RULE
    hard: ClassVar[bool] = True

    def __init__(self, margin: ReturnMargin | None = None):
        self.margin = margin  # the wind planners' margin kept in an observed wind (None: theirs)

    def allowed(
        self, obs: Observation, allowed: np.ndarray, floor: np.ndarray, q_values: QValues
    ) -> np.ndarray:
        wind = obs.get("wind")
        return allowed & safe_actions(obs["map"], obs["position"], obs["budget"], wind, self.margin)

    def identity(self) -> dict[str, Any]:
        out: dict[str, Any] = {"return_rule": self.rule}
        if self.margin is not None:  # what the rule keeps in wind
            out["wind_margin"] = {k: float(v) for k, v in vars(self.margin).items()}
        return out
