"""A trained agent as a policy: greedy π(s) = argmax_a Q(s, a) among the actions its rules
allow, for one observation or a batch.

An agent is a network plus an ordered list of rules (:mod:`~cpp_mujoco.agent.rules`): the
return mask (agents trained with it act only among the actions that keep the way home paid),
the revisit, finish and progress masks, symmetric Q (on every map, or on the maps it did not
learn in their own orientation). The agent file stores the list; results name it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from cpp_mujoco.agent.ddqn import mask_unsafe
from cpp_mujoco.agent.fcn_network import FCNQNetwork
from cpp_mujoco.agent.general_network import GeneralQNetwork
from cpp_mujoco.agent.network import QNetwork, observation_to_tensors
from cpp_mujoco.agent.rules import ReturnMask, Rule, make_rules, rule_metadata, rules_identity
from cpp_mujoco.agent.rules.symmetric_q import (
    SymmetricQ,
    SymmetricQUnseen,
    own_orientation_maps,
)
from cpp_mujoco.agent.shared_features import batch_rows, shared_q_values
from cpp_mujoco.grid.actions import NUM_ACTIONS
from cpp_mujoco.grid.way_home import ReturnMargin
from cpp_mujoco.maps import GridMap
from cpp_mujoco.maps.symmetry import map_images
from cpp_mujoco.protocol.policy import as_batch

FORWARD_CELLS = 2**20  # observations per forward pass × map cells: caps the conv activations


class MapSizeError(ValueError):
    """The observation's map size differs from the size the network was built for."""


class GreedyAgent:
    """``act(obs)``: one observation dict (``coverage`` of shape (H, W)) → int; a batch (leading
    dim N) → np.ndarray of N ints. ``network`` is the torch Q-network, ``rules`` what narrows
    the actions it chooses among (:func:`~cpp_mujoco.agent.rules.make_rules`), in order."""

    def __init__(
        self,
        network: QNetwork | GeneralQNetwork | FCNQNetwork,
        budget_scale: float,
        device: str | torch.device = "cpu",
        name: str = "ddqn",
        metadata: dict | None = None,
        rules: Sequence[Rule] = (),
    ):
        self.network = network.to(device).eval()
        self.rules = list(rules)
        self.budget_scale = float(budget_scale)
        self.device = torch.device(device)
        self.name = name
        self.metadata = dict(metadata or {})

    @property
    def rule_names(self) -> list[str]:
        return [r.name for r in self.rules]

    def with_rules(self, names: Sequence[str]) -> GreedyAgent:
        """This agent's network flown with the rules ``names`` instead (the return mask keeps
        its margin); the file's metadata is kept, results name the new rules."""
        rules = make_rules(names, self.wind_margin, own_orientation_maps(self.metadata))
        metadata = {**self.metadata, **rule_metadata([r.name for r in rules])}
        return GreedyAgent(
            self.network, self.budget_scale, self.device, self.name, metadata, rules
        )  # fmt: skip

    def _has(self, name: str) -> bool:
        return name in self.rule_names

    return_mask = property(lambda self: self._has("return-mask"))
    revisit_mask = property(lambda self: self._has("revisit-mask"))
    finish_mask = property(lambda self: self._has("finish-mask"))
    symmetric_q = property(lambda self: self._has("symmetric-q"))

    @property
    def wind_margin(self) -> ReturnMargin | None:
        """The margin the return mask keeps in an observed wind (None: the wind planners')."""
        return next((r.margin for r in self.rules if isinstance(r, ReturnMask)), None)

    @property
    def map_shape(self) -> tuple[int, int] | None:
        """The map size the network was built for; None for a network that flies any size
        (:class:`~cpp_mujoco.agent.general_network.GeneralQNetwork`,
        :class:`~cpp_mujoco.agent.fcn_network.FCNQNetwork`)."""
        if getattr(self.network, "any_size", False):
            return None
        return self.network.height, self.network.width

    def q_values(self, obs: dict[str, np.ndarray], rows: np.ndarray | None = None) -> np.ndarray:
        """The network's Q-values (N, 5) for a batch of observations. ``rows``: only those rows
        are read (the others are 0): a row's Q-values do not depend on its batch."""
        if rows is not None:
            part = {k: batch_rows(k, v, 0, None, rows) for k, v in obs.items()}
            q = np.zeros((int(np.shape(obs["coverage"])[0]), NUM_ACTIONS), dtype=np.float32)
            q[rows] = self.network_q_values(part)
            return q
        return self.network_q_values(obs)

    @torch.no_grad()
    def network_q_values(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The network's Q-values (N, 5) for a batch of observations, as it reads them."""
        shape = tuple(np.shape(obs["coverage"])[-2:])
        if self.map_shape is not None and shape != self.map_shape:
            raise MapSizeError(
                f"agent {self.name!r} was trained on {self.map_shape[0]}x{self.map_shape[1]} maps, "
                f"the observation is {shape[0]}x{shape[1]}"
            )
        if "obstacle" in obs and not self.reads_obstacles and np.any(obs["obstacle"]):
            raise MapSizeError(
                f"agent {self.name!r} reads no obstacle layer; this map has obstacles that hide "
                "what its camera sees"
            )
        n = int(np.shape(obs["coverage"])[0])
        cells = shape[0] * shape[1] if self.map_shape else self.network.input_cells(shape)
        step = max(1, FORWARD_CELLS // cells)  # bounds the activations' memory
        shared = shared_q_values(self, obs, step)  # a batch on one map: each grid read once
        if shared is not None:
            return shared
        parts = []
        for lo in range(0, max(n, 1), step):
            part = {k: batch_rows(k, v, lo, lo + step) for k, v in obs.items()}
            net = self.network
            grid, scalars = observation_to_tensors(
                part, self.budget_scale, self.device, net.wind_inputs, net.home_input,
                self.reads_obstacles,
            )  # fmt: skip
            parts.append(self.network(grid, scalars).cpu().numpy())
        return np.concatenate(parts)

    def fits(self, grid_map: GridMap) -> str | None:
        """Why this agent does not fit ``grid_map`` (None if it does): a per-map agent flies only
        the map it was trained on (its file's ``map_digest``) — with a symmetric-Q rule also
        that map turned or mirrored; a general agent flies any map.
        A network without an obstacle input fits no map with obstacles: it cannot tell what
        hides a target. The protocol refuses the misfit unless the user says so (``any_map``)."""
        if grid_map.has_obstacles and not self.reads_obstacles:
            return (
                f"agent {self.name} reads no obstacle layer; map {grid_map.label} has "
                f"{int(grid_map.obstacle.sum())} obstacle cells that hide what its camera sees"
            )
        trained = self.metadata.get("map_digest")
        if self.metadata.get("architecture", "paper") != "paper" or not trained:
            return None
        if trained == grid_map.digest:
            return None
        symmetric = self._has(SymmetricQ.name) or self._has(SymmetricQUnseen.name)
        if symmetric and trained in {m.digest for m in map_images(grid_map)}:
            return None  # it reads the map in its trained orientation too, among the 8 images
        return (
            f"agent {self.name} was trained on map {self.metadata.get('map')!r} (cells "
            f"{trained}), not on map {grid_map.label} (cells {grid_map.digest})"
        )

    @property
    def reads_obstacles(self) -> bool:
        """Whether the network takes the observation's ``obstacle`` layer."""
        return bool(getattr(self.network, "obstacle_input", False))

    def identity(self) -> dict[str, Any]:
        """What results record of this agent (:func:`~cpp_mujoco.protocol.policy.policy_identity`):
        its network's inputs, and each of its rules by its versioned rule string."""
        out: dict[str, Any] = {}
        kwargs = getattr(self.network, "kwargs", None)
        if isinstance(kwargs, dict):  # its inputs too (moves home, moves to new targets, wind)
            out["network"] = dict(kwargs)
        return {**out, **rules_identity(self.rules)}

    def reset(self, num_episodes: int, seed: int | None = None) -> None:
        """Episode start: the rules with a memory forget it (the Q-values keep no state)."""
        for rule in self.rules:
            rule.reset(num_episodes)

    def act(self, obs: dict[str, np.ndarray]):
        single = np.ndim(obs["coverage"]) == 2
        actions = self.act_active(as_batch(obs) if single else obs, None)
        return int(actions[0]) if single else actions

    def act_active(self, obs: dict[str, np.ndarray], active: np.ndarray | None) -> np.ndarray:
        """The actions of a batch; only the rows ``active`` marks are read by the network (the
        episode loops give the others a landing their env ignores), every row by the rules, so
        a rule's memory sees each step of its episode as :meth:`act` would."""
        rows = None if active is None or np.all(active) else np.flatnonzero(active)
        if not self.rules:
            return torch.from_numpy(self.q_values(obs, rows)).argmax(dim=1).numpy()
        n = int(np.shape(obs["coverage"])[0])

        def read(o: dict[str, np.ndarray]) -> np.ndarray:
            """Q-values of the batch, or of k stacked copies of it (symmetric Q's images): the
            active rows of each copy."""
            if rows is None:
                return self.q_values(o)
            copies = int(np.shape(o["coverage"])[0]) // n
            return self.q_values(o, (rows + n * np.arange(copies)[:, None]).ravel())

        allowed = floor = np.ones((n, NUM_ACTIONS), dtype=bool)
        for rule in self.rules:
            allowed = rule.allowed(obs, allowed, floor, read)
            if rule.hard:
                floor = allowed
        live = allowed if rows is None else allowed[rows]
        if (live.sum(axis=1) == 1).all():  # the rules chose (symmetric Q): no network read
            return allowed.argmax(axis=1)
        q = torch.from_numpy(self.q_values(obs, rows))
        return mask_unsafe(q, torch.from_numpy(allowed)).argmax(dim=1).numpy()

    __call__ = act

    def predict(
        self,
        observation: dict[str, np.ndarray],
        state=None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, None]:
        """Stable-Baselines3's interface (``evaluate_policy``, ``model.predict`` habits):
        (actions, no recurrent state). The agent is greedy, so only ``deterministic=True``."""
        if not deterministic:
            raise ValueError(
                f"agent {self.name!r} is greedy (argmax Q); deterministic=False is not available"
            )
        return np.asarray(self.act(observation)), None
