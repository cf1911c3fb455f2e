"""The paper's Q-network (Theile et al. 2020, §III-C, Table I).

Input: five H×W channels (landing, target, no-fly, coverage, one-hot position) and the remaining
movement budget as one scalar. Two 5×5 convolutions with 16 filters keep the spatial shape; every
channel is zero-padded except the FIRST layer's no-fly channel, which is padded with ones (outside
the grid is no-fly). Flatten, concatenate the budget, three fully-connected layers of 256 with ReLU,
a linear output of 5 Q-values. For a 16×16 map: 1,190,389 trainable parameters.

A wind-robust agent (``wind_inputs=True``) also reads the observed steady wind beside the budget:
its east and north components and its speed, times :data:`WIND_GAIN` — three more inputs to the
first dense layer.

A general network (:mod:`~cpp_mujoco.agent.general_network`) may also read the moves home
(``home_input``, :mod:`~cpp_mujoco.agent.home_input`: the fewest moves from the UAV's cell to a
landing cell, scaled as the budget, last among the scalars) and the obstacle layer
(``obstacle_input``, :mod:`~cpp_mujoco.agent.obstacle_input`: a sixth grid channel).
:func:`scalar_inputs` and :func:`observation_to_tensors` are the one implementation every caller
shares (policy, training collection, replay minibatches).
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from cpp_mujoco.agent.home_input import moves_home
from cpp_mujoco.grid.actions import NUM_ACTIONS

IN_CHANNELS = 5  # landing, target, nfz, coverage, position
LANDING_CHANNEL, TARGET_CHANNEL, NFZ_CHANNEL, COVERAGE_CHANNEL, POSITION_CHANNEL = range(5)
OBSTACLE_CHANNEL = IN_CHANNELS  # the sixth channel of a network with the obstacle input
# the wind inputs are m/s × this. Like the raw budget (25..75, see TrainConfig.budget_scale) they
# must not be small beside 4,096 conv features: measured on map A, wind / 10 m/s left the policy
# flying its calm tour in a steady 9 m/s wind (42 % landing at budget 45 after 6,000 updates)
WIND_GAIN = 5.0


def dense_head(width_in: int, hidden: int, num_hidden: int) -> nn.Sequential:
    """``num_hidden`` ReLU layers of ``hidden`` units, then the Q-values: every network's head
    (its parameter names, ``head.0.weight`` …, are what checkpoints hold)."""
    layers: list[nn.Module] = []
    for _ in range(num_hidden):
        layers += [nn.Linear(width_in, hidden), nn.ReLU()]
        width_in = hidden
    layers.append(nn.Linear(width_in, NUM_ACTIONS))
    return nn.Sequential(*layers)


class QNetwork(nn.Module):
    """Q(s, ·) for an H×W map. ``forward(grid, scalars)``: grid (B,5,H,W) float, scalars (B,1)
    the scaled budget, or (B,4) budget and wind with ``wind_inputs`` (:func:`scalar_inputs`)."""

    home_input = False  # the paper's network reads no moves home (a general network may)
    obstacle_input = False  # nor obstacles: GreedyAgent refuses maps with them

    def __init__(
        self,
        height: int = 16,
        width: int = 16,
        conv_filters: int = 16,
        kernel_size: int = 5,
        hidden: int = 256,
        num_hidden: int = 3,
        wind_inputs: bool = False,
    ):
        super().__init__()
        if kernel_size % 2 != 1:
            raise ValueError(f"kernel_size must be odd to keep the shape, got {kernel_size}")
        self.height, self.width = height, width
        self.wind_inputs = bool(wind_inputs)
        self.num_scalars = 4 if self.wind_inputs else 1
        self.pad = kernel_size // 2
        self.conv1 = nn.Conv2d(IN_CHANNELS, conv_filters, kernel_size, padding=0)
        self.conv2 = nn.Conv2d(conv_filters, conv_filters, kernel_size, padding=self.pad)
        width_in = conv_filters * height * width + self.num_scalars  # + budget (and wind)
        self.head = dense_head(width_in, hidden, num_hidden)

    def pad_input(self, grid: torch.Tensor) -> torch.Tensor:
        """Shape-keeping padding of the first layer's input: ones for no-fly, zeros elsewhere."""
        p = self.pad
        padded = F.pad(grid, (p, p, p, p), value=0.0)
        nfz = F.pad(grid[:, NFZ_CHANNEL : NFZ_CHANNEL + 1], (p, p, p, p), value=1.0)
        return torch.cat([padded[:, :NFZ_CHANNEL], nfz, padded[:, NFZ_CHANNEL + 1 :]], dim=1)

    def forward(self, grid: torch.Tensor, scalars: torch.Tensor) -> torch.Tensor:
        x = F.relu(self.conv1(self.pad_input(grid)))
        x = F.relu(self.conv2(x))
        x = torch.cat([x.flatten(1), scalars.reshape(-1, self.num_scalars)], dim=1)
        return self.head(x)

    def load_narrower(self, source: QNetwork) -> None:
        """Start from ``source``'s weights (same map size; it may lack wind inputs): the wind
        inputs' weights start at zero, so this network first acts exactly as ``source``."""
        check_can_start_from(source, self.height, self.width, self.wind_inputs)
        state = source.state_dict()
        first = self.head[0].weight
        if state["head.0.weight"].shape[1] != first.shape[1]:
            widened = torch.zeros_like(first)
            widened[:, : state["head.0.weight"].shape[1]] = state["head.0.weight"]
            state["head.0.weight"] = widened
        self.load_state_dict(state)


def check_can_start_from(source: QNetwork, height: int, width: int, wind_inputs: bool) -> None:
    """``ValueError`` unless an H×W network (with or without wind inputs) can start from
    ``source``'s weights (:meth:`QNetwork.load_narrower`): same map size, no inputs it lacks."""
    if not isinstance(source, QNetwork):
        raise ValueError(
            f"cannot start a {height}x{width} per-map network from a {type(source).__name__} "
            "(a general network's weights have another shape)"
        )
    if (source.height, source.width) != (height, width):
        raise ValueError(
            f"cannot start a {height}x{width} network from a {source.height}x{source.width} one"
        )
    if source.wind_inputs and not wind_inputs:
        raise ValueError(
            "cannot start a network without wind inputs from one with them (train in the wind "
            "option: wind_max_speed > 0)"
        )


def count_parameters(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters() if p.requires_grad)


def scalar_inputs(budget, wind, budget_scale: float, wind_inputs: bool, home=None) -> np.ndarray:
    """The network's scalar inputs (N, 1–5) float32: budget / ``budget_scale`` (a fixed
    preprocessing stored with the weights); for a wind network the wind's east and north
    components and its speed, × WIND_GAIN; then, if ``home`` (the moves home, (N,)) is given,
    home / ``budget_scale`` — scaled as the budget, so "budget − moves home" is one difference."""
    scale = np.float32(budget_scale)
    budget = np.asarray(budget, dtype=np.float32).reshape(-1, 1) / scale
    parts = [budget]
    if wind_inputs:
        wind = np.asarray(wind, dtype=np.float32).reshape(-1, 2)
        speed = np.sqrt((wind**2).sum(axis=1, keepdims=True))
        parts += [wind * np.float32(WIND_GAIN), speed * np.float32(WIND_GAIN)]
    if home is not None:
        parts.append(np.asarray(home, dtype=np.float32).reshape(-1, 1) / scale)
    return np.concatenate(parts, axis=1) if len(parts) > 1 else budget


def observation_to_tensors(
    obs: dict[str, np.ndarray],
    budget_scale: float,
    device: torch.device | str = "cpu",
    wind_inputs: bool = False,
    home_input: bool = False,
    obstacle_input: bool = False,
) -> tuple[torch.Tensor, torch.Tensor]:
    """A batched observation dict (leading dim N; ``map`` (3,H,W) shared or (N,3,H,W) per row)
    → (grid (N,5,H,W), scalars) float tensors (:func:`scalar_inputs`); an observation without
    ``wind`` counts as calm air. ``home_input``: the moves home from the map
    (:func:`~cpp_mujoco.agent.home_input.moves_home`, cached per map). ``obstacle_input``: the
    grid is (N,6,H,W), its last channel the ``obstacle`` layer ((H,W) shared or (N,H,W); zeros
    where the observation has none: a map without obstacles)."""
    coverage = np.asarray(obs["coverage"])
    n = coverage.shape[0]
    maps = np.broadcast_to(np.asarray(obs["map"]), (n, 3, *coverage.shape[1:]))
    parts = [maps, coverage[:, None], np.asarray(obs["position"])[:, None]]
    if obstacle_input:
        obstacle = obs.get("obstacle")
        if obstacle is None:
            parts.append(np.zeros((n, 1, *coverage.shape[1:]), dtype=np.float32))
        else:
            parts.append(np.broadcast_to(np.asarray(obstacle), coverage.shape)[:, None])
    grid = np.concatenate(parts, axis=1, dtype=np.float32)
    scalars = observation_scalars(obs, budget_scale, device, wind_inputs, home_input)
    return torch.from_numpy(grid).to(device), scalars


def observation_scalars(
    obs: dict[str, np.ndarray],
    budget_scale: float,
    device: torch.device | str = "cpu",
    wind_inputs: bool = False,
    home_input: bool = False,
) -> torch.Tensor:
    """The scalars of :func:`observation_to_tensors` alone (:func:`scalar_inputs`)."""
    n = np.shape(obs["coverage"])[0]
    wind = obs.get("wind", np.zeros((n, 2), dtype=np.float32)) if wind_inputs else None
    home = moves_home(obs["map"], obs["position"]) if home_input else None
    budget = np.reshape(obs["budget"], (n, 1))
    scalars = scalar_inputs(budget, wind, budget_scale, wind_inputs, home)
    return torch.from_numpy(scalars).to(device)
