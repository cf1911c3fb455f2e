"""A trained agent as a policy: greedy π(s) = argmax_a Q(s, a), for one observation or a batch;
an agent trained with the return mask takes the argmax over the actions that keep its way home
paid (:func:`~cpp_mujoco.agent.home_input.safe_actions`), as it was trained to; one flown with
the revisit mask (:mod:`~cpp_mujoco.agent.revisit_mask`) also leaves out the moves back into a
fruitless cell it has flown through, and keeps that memory per episode (``reset``); one flown
with the finish mask (:mod:`~cpp_mujoco.agent.finish_mask`) does not land while an unseen target
is still within reach."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from cpp_mujoco.agent.ddqn import mask_unsafe
from cpp_mujoco.agent.fcn_network import FCNQNetwork
from cpp_mujoco.agent.finish_mask import FINISH_RULE, finish_allowed
from cpp_mujoco.agent.general_network import GeneralQNetwork
from cpp_mujoco.agent.home_input import safe_actions
from cpp_mujoco.agent.network import QNetwork, observation_to_tensors
from cpp_mujoco.agent.revisit_mask import REVISIT_RULE, RevisitMemory
from cpp_mujoco.grid.actions import NUM_ACTIONS
from cpp_mujoco.grid.return_rule import RETURN_RULE
from cpp_mujoco.grid.symmetry import SYMMETRIC_Q_RULE, symmetric_q_values
from cpp_mujoco.grid.way_home import ReturnMargin
from cpp_mujoco.protocol.policy import as_batch

FORWARD_CELLS = 2**20  # observations per forward pass × map cells: caps the conv activations


class MapSizeError(ValueError):
    """The observation's map size differs from the size the network was built for."""


class GreedyAgent:
    """``act(obs)``: one observation dict (``coverage`` of shape (H, W)) → int; a batch (leading
    dim N) → np.ndarray of N ints. ``network`` is the torch Q-network; ``return_mask``: act only
    among the return rule's safe actions (agents trained with it), in an observed wind with
    ``wind_margin`` (the margin of the wind planners it learned from; None: their default);
    ``revisit_mask``: nor the moves back into a cell flown through since the coverage last grew
    that shows no unseen target (:mod:`~cpp_mujoco.agent.revisit_mask`); ``finish_mask``: nor
    the landing while a cell showing an unseen target can be reached and left for home
    (:mod:`~cpp_mujoco.agent.finish_mask`); ``symmetric_q``: the
    argmax of the Q-values averaged over the map's rotations and mirror images."""

    def __init__(
        self,
        network: QNetwork | GeneralQNetwork | FCNQNetwork,
        budget_scale: float,
        device: str | torch.device = "cpu",
        name: str = "ddqn",
        metadata: dict | None = None,
        return_mask: bool = False,
        wind_margin: ReturnMargin | None = None,
        revisit_mask: bool = False,
        symmetric_q: bool = False,
        finish_mask: bool = False,
    ):
        self.network = network.to(device).eval()
        self.return_mask = bool(return_mask)
        self.wind_margin = wind_margin
        self.revisit_mask = bool(revisit_mask)
        self.symmetric_q = bool(symmetric_q)
        self.finish_mask = bool(finish_mask)
        self.memory = RevisitMemory()
        self.budget_scale = float(budget_scale)
        self.device = torch.device(device)
        self.name = name
        self.metadata = dict(metadata or {})

    @property
    def map_shape(self) -> tuple[int, int] | None:
        """The map size the network was built for; None for a network that flies any size
        (:class:`~cpp_mujoco.agent.general_network.GeneralQNetwork`,
        :class:`~cpp_mujoco.agent.fcn_network.FCNQNetwork`)."""
        if getattr(self.network, "any_size", False):
            return None
        return self.network.height, self.network.width

    def q_values(self, obs: dict[str, np.ndarray], rows: np.ndarray | None = None) -> np.ndarray:
        """Q-values (N, 5) for a batch of observations; with ``symmetric_q`` their mean over
        the map's images (:func:`~cpp_mujoco.grid.symmetry.symmetric_q_values`). ``rows``: only
        those rows are read (the others are 0): a row's Q-values do not depend on its batch."""
        if rows is not None:
            part = {k: _rows(k, v, 0, None, rows) for k, v in obs.items()}
            q = np.zeros((int(np.shape(obs["coverage"])[0]), NUM_ACTIONS), dtype=np.float32)
            q[rows] = self.q_values(part)
            return q
        if self.symmetric_q:
            return symmetric_q_values(self.network_q_values, obs)
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
        n = int(np.shape(obs["coverage"])[0])
        cells = shape[0] * shape[1] if self.map_shape else self.network.input_cells(shape)
        step = max(1, FORWARD_CELLS // cells)  # bounds the activations' memory
        parts = []
        for lo in range(0, max(n, 1), step):
            part = {k: _rows(k, v, lo, lo + step) for k, v in obs.items()}
            net = self.network
            grid, scalars = observation_to_tensors(
                part, self.budget_scale, self.device, net.wind_inputs, net.home_input
            )
            parts.append(self.network(grid, scalars).cpu().numpy())
        return np.concatenate(parts)

    def identity(self) -> dict[str, Any]:
        """What results record of this agent (:func:`~cpp_mujoco.protocol.policy.policy_identity`):
        its network's inputs, and each rule it acts with by its versioned rule string."""
        out: dict[str, Any] = {}
        kwargs = getattr(self.network, "kwargs", None)
        if isinstance(kwargs, dict):  # its inputs too (moves home, moves to new targets, wind)
            out["network"] = dict(kwargs)
        out["return_mask"] = self.return_mask
        if self.return_mask:
            out["return_rule"] = RETURN_RULE
            if self.wind_margin is not None:  # what the rule keeps in wind
                out["wind_margin"] = {k: float(v) for k, v in vars(self.wind_margin).items()}
        out["revisit_mask"] = self.revisit_mask
        if self.revisit_mask:
            out["revisit_rule"] = REVISIT_RULE
        out["finish_mask"] = self.finish_mask
        if self.finish_mask:
            out["finish_rule"] = FINISH_RULE
        if self.symmetric_q:  # recorded only when on: results keep their keys
            out["symmetric_q"] = SYMMETRIC_Q_RULE
        return out

    def reset(self, num_episodes: int, seed: int | None = None) -> None:
        """Episode start: the revisit mask forgets the cells flown (the Q-values keep no state)."""
        self.memory.reset()

    def act(self, obs: dict[str, np.ndarray]):
        single = np.ndim(obs["coverage"]) == 2
        actions = self.act_active(as_batch(obs) if single else obs, None)
        return int(actions[0]) if single else actions

    def act_active(self, obs: dict[str, np.ndarray], active: np.ndarray | None) -> np.ndarray:
        """The actions of a batch; only the rows ``active`` marks are read by the network (the
        episode loops give the others a landing their env ignores), every row by the rules, so
        a rule's memory sees each step of its episode as :meth:`act` would."""
        rows = None if active is None or np.all(active) else np.flatnonzero(active)
        q = torch.from_numpy(self.q_values(obs, rows))
        allowed = None
        if self.return_mask:
            wind = obs.get("wind")
            allowed = safe_actions(
                obs["map"], obs["position"], obs["budget"], wind, self.wind_margin
            )
        if self.revisit_mask or self.finish_mask:
            if allowed is None:
                allowed = np.ones(tuple(q.shape), dtype=bool)
            before_revisit = allowed
            if self.revisit_mask:
                allowed = self.memory.allowed(obs, allowed)
            if self.finish_mask:
                allowed = finish_allowed(obs, allowed, wider=before_revisit)
        if allowed is not None:
            q = mask_unsafe(q, torch.from_numpy(allowed))
        return q.argmax(dim=1).numpy()

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


def _rows(key: str, value, lo: int, hi: int | None, rows: np.ndarray | None = None) -> np.ndarray:
    """Rows lo:hi (or ``rows``) of a batched array; a map shared by the batch ((3, H, W)) stays
    whole."""
    value = np.asarray(value)
    if key == "map" and value.ndim == 3:
        return value
    return value[rows] if rows is not None else value[lo:hi]
