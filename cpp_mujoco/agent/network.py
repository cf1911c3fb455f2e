"""The paper's Q-network (Theile et al. 2020, §III-C, Table I).

Input: five H×W channels (landing, target, no-fly, coverage, one-hot position) and the remaining
movement budget as one scalar. Two 5×5 convolutions with 16 filters keep the spatial shape; every
channel is zero-padded except the FIRST layer's no-fly channel, which is padded with ones (outside
the grid is no-fly). Flatten, concatenate the budget, three fully-connected layers of 256 with ReLU,
a linear output of 5 Q-values. For a 16×16 map: 1,190,389 trainable parameters.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from cpp_mujoco.grid.actions import NUM_ACTIONS

IN_CHANNELS = 5  # landing, target, nfz, coverage, position
NFZ_CHANNEL = 2


class QNetwork(nn.Module):
    """Q(s, ·) for an H×W map. ``forward(grid, budget)``: grid (B,5,H,W) float, budget (B,1) float
    (already scaled, see :func:`observation_to_tensors`)."""

    def __init__(
        self,
        height: int = 16,
        width: int = 16,
        conv_filters: int = 16,
        kernel_size: int = 5,
        hidden: int = 256,
        num_hidden: int = 3,
    ):
        super().__init__()
        if kernel_size % 2 != 1:
            raise ValueError(f"kernel_size must be odd to keep the shape, got {kernel_size}")
        self.height, self.width = height, width
        self.pad = kernel_size // 2
        self.conv1 = nn.Conv2d(IN_CHANNELS, conv_filters, kernel_size, padding=0)
        self.conv2 = nn.Conv2d(conv_filters, conv_filters, kernel_size, padding=self.pad)
        layers: list[nn.Module] = []
        width_in = conv_filters * height * width + 1  # + budget scalar
        for _ in range(num_hidden):
            layers += [nn.Linear(width_in, hidden), nn.ReLU()]
            width_in = hidden
        layers.append(nn.Linear(width_in, NUM_ACTIONS))
        self.head = nn.Sequential(*layers)

    def pad_input(self, grid: torch.Tensor) -> torch.Tensor:
        """Shape-keeping padding of the first layer's input: ones for no-fly, zeros elsewhere."""
        p = self.pad
        padded = F.pad(grid, (p, p, p, p), value=0.0)
        nfz = F.pad(grid[:, NFZ_CHANNEL : NFZ_CHANNEL + 1], (p, p, p, p), value=1.0)
        return torch.cat([padded[:, :NFZ_CHANNEL], nfz, padded[:, NFZ_CHANNEL + 1 :]], dim=1)

    def forward(self, grid: torch.Tensor, budget: torch.Tensor) -> torch.Tensor:
        x = F.relu(self.conv1(self.pad_input(grid)))
        x = F.relu(self.conv2(x))
        x = torch.cat([x.flatten(1), budget.reshape(-1, 1)], dim=1)
        return self.head(x)


def count_parameters(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters() if p.requires_grad)


def observation_to_tensors(
    obs: dict[str, np.ndarray], budget_scale: float, device: torch.device | str = "cpu"
) -> tuple[torch.Tensor, torch.Tensor]:
    """A batched observation dict (leading dim N) → (grid (N,5,H,W), budget (N,1)) float tensors.

    The budget is divided by ``budget_scale`` (the training config's max budget), a fixed
    preprocessing stored with the weights.
    """
    coverage = np.asarray(obs["coverage"])
    n = coverage.shape[0]
    maps = np.broadcast_to(np.asarray(obs["map"]), (n, 3, *coverage.shape[1:]))
    grid = np.concatenate(
        [maps, coverage[:, None], np.asarray(obs["position"])[:, None]], axis=1, dtype=np.float32
    )
    budget = np.asarray(obs["budget"], dtype=np.float32).reshape(n, 1) / budget_scale
    return torch.from_numpy(grid).to(device), torch.from_numpy(budget).to(device)
