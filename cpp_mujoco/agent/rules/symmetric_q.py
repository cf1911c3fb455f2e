"""Symmetric Q as a rule: the action the Q-values averaged over the map's images rank first.

The grid MDP has no preferred direction, so the mean of the network's Q-values read on the 8
rotations and mirror images of a state (:func:`~cpp_mujoco.grid.symmetry.symmetric_q_values`)
is an estimate of Q that is itself symmetric. As the last rule it narrows each row to that
mean's argmax among the actions the rules before it allow, so the agent takes it.

On a map the agent learned in its own orientation only (a per-map agent's map, a general
agent's named maps A, B, C) the other images are maps it never saw, and the mean reads worse
than the map's own image; ``symmetric-q-unseen`` takes the mean everywhere else and the map's
own reading there (the maps named by digest in the agent file, :func:`own_orientation_maps`).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from typing import Any, ClassVar

import numpy as np
import torch

from cpp_mujoco.agent.ddqn import mask_unsafe
from cpp_mujoco.agent.rules.base import Observation, QValues, Stateless, map_groups
from cpp_mujoco.grid.symmetry import SYMMETRIC_Q_RULE, symmetric_q_values
from cpp_mujoco.maps.format import layers_digest

# what results record of the rule (policy_identity); a changed rule gets a new name here
SYMMETRIC_Q_UNSEEN_RULE = (
    "d4-mean-unseen-v1 (d4-mean-v1's averaged Q-values, except on a map the agent learned in its "
    "own orientation only, by digest, where its own reading)"
)
_NAMED_DIGEST = re.compile(r"\(([0-9a-f]{12})\)$")  # a general file's "A (242dcad1db2a)"


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


class SymmetricQUnseen(SymmetricQ):
    """Symmetric Q except on the maps the agent learned in their own orientation only, where
    the rows are left to the network's own reading (``own_orientation``: their digests)."""

    name: ClassVar[str] = "symmetric-q-unseen"
    rule: ClassVar[str] = SYMMETRIC_Q_UNSEEN_RULE

    def __init__(self, own_orientation: Iterable[str] = ()):
        self.own_orientation = frozenset(own_orientation)

    def allowed(
        self, obs: Observation, allowed: np.ndarray, floor: np.ndarray, q_values: QValues
    ) -> np.ndarray:
        own = own_orientation_rows(obs, self.own_orientation)
        if own.all():
            return allowed
        out = super().allowed(obs, allowed, floor, q_values)
        out[own] = allowed[own]
        return out

    def identity(self) -> dict[str, Any]:
        return {"symmetric_q_unseen": self.rule, "own_orientation": sorted(self.own_orientation)}


def own_orientation_rows(obs: Observation, digests: frozenset[str]) -> np.ndarray:
    """(N,) bool: the rows of a batch flown on a map whose digest is among ``digests``."""
    own = np.zeros(int(np.shape(obs["coverage"])[0]), dtype=bool)
    if digests:
        for part, rows in map_groups(obs):
            own[rows] = layers_digest(part["map"], part.get("obstacle")) in digests
    return own


def own_orientation_maps(metadata: Mapping[str, Any]) -> frozenset[str]:
    """The digests of the maps an agent file learned in their own orientation only: a per-map
    agent's map (``map_digest``), a general agent's named maps (``train_maps.named``) unless
    its config trained them in all 8 images (``named_symmetries``)."""
    config = metadata.get("config") or {}
    named = [] if config.get("named_symmetries") else (metadata.get("train_maps") or {})
    names = named.get("named", []) if isinstance(named, Mapping) else []
    digests = {m.group(1) for m in map(_NAMED_DIGEST.search, names) if m}
    per_map = metadata.get("architecture", "paper") == "paper"  # a general file's is its pool's
    if per_map and isinstance(metadata.get("map_digest"), str):
        digests.add(metadata["map_digest"])
    return frozenset(digests)
