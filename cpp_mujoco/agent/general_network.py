"""A Q-network for maps of any size: Theile et al.'s global-local design (ICAR 2021).

The paper's network (:mod:`cpp_mujoco.agent.network`) flattens an H×W feature map into its dense
layers, so its weights fit one map size. To fly maps it has never seen, of 16×16 and 32×32 alike,
this network first centres the map on the UAV — a (2S−1)² canvas with the UAV in the middle,
no-fly outside the map, S = max(``max_side``, H, W) — and reads it twice:

* **local**: the central ``local_size``² crop at full resolution (what is next to the UAV);
* **global**: the whole canvas average-pooled to ``global_size``² (where the rest of the targets,
  the landing zone and the walls lie; with the default 63 → 21 each global cell is 3×3 cells).

Two unpadded ("valid") 5×5 convolutions per view, as in Theile et al.'s code, then both views
flattened, the budget (and the observed wind, × ``WIND_GAIN``, like ``QNetwork(wind_inputs=True)``;
with ``home_input`` the moves home, :mod:`~cpp_mujoco.agent.home_input`; with ``target_input``
the moves to new targets after each action, :mod:`~cpp_mujoco.agent.target_input`) appended,
three dense layers of 256 and the 5 Q-values. Every tensor after the centring has a fixed
shape, so one set of weights flies every map size; and because the canvas has a fixed side for
all maps up to ``max_side``, a map padded with no-fly cells gives exactly the Q-values of the
map itself — a mixed 16/32 minibatch is padded to 32×32 and stacked (:func:`pad_grids`). The
views are computed from the map without building the canvas
(:mod:`~cpp_mujoco.agent.centred_views`). With
``obstacle_input`` the grid has a sixth channel, the obstacle layer
(:mod:`~cpp_mujoco.agent.obstacle_input`), zero outside the map and on the padding like every
channel but no-fly.

The alternative, measured against it: :mod:`cpp_mujoco.agent.fcn_network`, fully convolutional
with global pooling (no flatten at all, also size-independent, but it must learn long-range
context through depth, where the global view hands it over directly).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from cpp_mujoco.agent.centred_views import MapViewCache
from cpp_mujoco.agent.network import IN_CHANNELS, NFZ_CHANNEL, dense_head
from cpp_mujoco.agent.target_input import NUM_FEATURES as TARGET_FEATURES
from cpp_mujoco.agent.target_input import moves_to_unseen

ARCHITECTURE = "general"  # what a checkpoint of this network records under "architecture"
# network_kwargs a checkpoint may hold: name → (smallest value, largest value)
KWARG_RANGES = {
    "local_size": (1, 255),
    "global_size": (1, 255),
    "max_side": (1, 512),
    "conv_filters": (1, 1024),
    "kernel_size": (1, 31),
    "hidden": (1, 16384),
    "num_hidden": (0, 16),
}
WIND_SCALARS = 3  # east, north and speed (network.scalar_inputs)
INPUT_FLAGS = ("wind_inputs", "home_input")  # optional bool network_kwargs: the scalar inputs
# optional bool network_kwargs, recorded only when on (files from before them rebuild as they were)
OBSTACLE_FLAG, TARGET_FLAG = "obstacle_input", "target_input"


class GeneralQNetwork(nn.Module):
    """Q(s, ·) for a map of any size. ``forward(grid, scalars)`` as :class:`QNetwork`'s: grid
    (B,5,H,W) float (any H, W; one size per call; (B,6,H,W) with ``obstacle_input``: the
    obstacle layer last, :mod:`~cpp_mujoco.agent.obstacle_input`), scalars
    (B, :attr:`num_scalars`): the scaled budget, then wind with ``wind_inputs`` and the moves
    home with ``home_input`` (:func:`~cpp_mujoco.agent.network.scalar_inputs`)."""

    any_size = True  # GreedyAgent: no map-size check
    grid_layers = ("local_conv.0.weight", "global_conv.0.weight")  # the layers reading the grid

    def __init__(
        self,
        local_size: int = 17,
        global_size: int = 21,
        max_side: int = 32,
        conv_filters: int = 16,
        kernel_size: int = 5,
        hidden: int = 256,
        num_hidden: int = 3,
        wind_inputs: bool = False,
        home_input: bool = False,
        target_input: bool = False,
        obstacle_input: bool = False,
    ):
        super().__init__()
        if local_size % 2 != 1:
            raise ValueError(f"local_size must be odd (centred on the UAV), got {local_size}")
        shrink = 2 * (kernel_size - 1)  # two valid convolutions
        if min(local_size, global_size) <= shrink:
            raise ValueError(
                f"local_size and global_size must exceed {shrink} for two {kernel_size}x"
                f"{kernel_size} convolutions, got {local_size} and {global_size}"
            )
        if local_size > 2 * max_side - 1:
            raise ValueError(f"local_size {local_size} exceeds the canvas {2 * max_side - 1}")
        self.kwargs = dict(
            local_size=local_size, global_size=global_size, max_side=max_side,
            conv_filters=conv_filters, kernel_size=kernel_size, hidden=hidden,
            num_hidden=num_hidden, wind_inputs=bool(wind_inputs), home_input=bool(home_input),
        )  # fmt: skip
        for flag, on in ((TARGET_FLAG, target_input), (OBSTACLE_FLAG, obstacle_input)):
            if on:  # recorded only when on: files from before the option rebuild as they were
                self.kwargs[flag] = True
        self.target_input, self.obstacle_input = bool(target_input), bool(obstacle_input)
        self.local_size, self.global_size, self.max_side = local_size, global_size, max_side
        self.height = self.width = None  # any map size
        self.wind_inputs, self.home_input = bool(wind_inputs), bool(home_input)
        self.num_scalars = num_scalars(self.wind_inputs, self.home_input)
        channels = IN_CHANNELS + self.obstacle_input
        self.local_conv = _conv_pair(channels, conv_filters, kernel_size)
        self.global_conv = _conv_pair(channels, conv_filters, kernel_size)
        features = conv_filters * ((local_size - shrink) ** 2 + (global_size - shrink) ** 2)
        # the inputs before the moves to new targets (target_input.widen_for_target_input)
        self.features_before_target = features + self.num_scalars
        extra = TARGET_FEATURES if self.target_input else 0
        self.head = dense_head(self.features_before_target + extra, hidden, num_hidden)
        self.view_cache: MapViewCache | None = None  # the last map's views (not weights)

    def input_cells(self, shape: tuple[int, int]) -> int:
        """Cells of the canvas an H×W map is centred on (a bound on what a forward pass holds
        per row; the views hold less)."""
        return (2 * max(self.max_side, *shape) - 1) ** 2

    def views(self, grid: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(local (B,5,l,l), global (B,5,g,g)) views of the map centred on the UAV: the crop
        and the average pool of :func:`~cpp_mujoco.agent.centred_views.centre_on_uav`'s
        canvas, without building the canvas; a batch on one map reads its map's layers from
        a per-cell table (:class:`~cpp_mujoco.agent.centred_views.MapViewCache`)."""
        side = max(self.max_side, *grid.shape[-2:])
        if self.view_cache is None or self.view_cache.sizes[0] != side:
            self.view_cache = MapViewCache(side, self.local_size, self.global_size)
        return self.view_cache.views(grid)

    def forward(self, grid: torch.Tensor, scalars: torch.Tensor) -> torch.Tensor:
        return self.q_from_features(self.features(grid), scalars)

    def features(self, grid: torch.Tensor) -> torch.Tensor:
        """(B, F): what the network reads of the grid alone — both views through their
        convolutions, then the moves to new targets (with ``target_input``). Rows with the same
        grid share them whatever their scalars (:mod:`~cpp_mujoco.agent.shared_features`)."""
        local, global_ = self.views(grid)
        parts = [self.local_conv(local).flatten(1), self.global_conv(global_).flatten(1)]
        if self.target_input:
            parts.append(moves_to_unseen(grid, 2 * self.max_side))
        return torch.cat(parts, dim=1)

    def q_from_features(self, features: torch.Tensor, scalars: torch.Tensor) -> torch.Tensor:
        """The Q-values from :meth:`features` and the scalar inputs: the dense head reads the
        convolutions' features, the scalars, then the moves to new targets."""
        conv = features.shape[1] - (TARGET_FEATURES if self.target_input else 0)
        parts = [features[:, :conv], scalars.reshape(-1, self.num_scalars), features[:, conv:]]
        return self.head(torch.cat(parts, dim=1))


def _conv_pair(channels: int, filters: int, kernel_size: int) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(channels, filters, kernel_size),
        nn.ReLU(),
        nn.Conv2d(filters, filters, kernel_size),
        nn.ReLU(),
    )


def pad_grids(grid: np.ndarray, side: int) -> np.ndarray:
    """(B,5,h,w) float grids → (B,5,side,side): the map padded with no-fly cells at the bottom
    and right. The general network's Q-values do not change (the canvas already holds no-fly
    there), so transitions of 16×16 and 32×32 maps share one minibatch."""
    b, c, h, w = grid.shape
    if (h, w) == (side, side):
        return grid
    out = np.zeros((b, c, side, side), dtype=grid.dtype)
    out[:, NFZ_CHANNEL] = 1.0
    out[:, :, :h, :w] = grid
    return out


def check_general_kwargs(kwargs: object) -> str | None:
    """None if ``kwargs`` can build a :class:`GeneralQNetwork`, else what is wrong."""
    flags = (*INPUT_FLAGS, TARGET_FLAG, OBSTACLE_FLAG)
    return check_network_kwargs(kwargs, KWARG_RANGES, "general", flags)


def widen_for_wind_inputs(state: dict[str, torch.Tensor], network: GeneralQNetwork) -> dict:
    """Weights of ``network``'s design without the wind inputs → ``network``'s, giving the very
    same Q-values in any wind: three zero columns after the budget's (the scalar inputs are the
    budget, the wind's three, the moves home); training in wind then learns to use them."""
    key = "head.0.weight"
    weight = state[key]
    total = network.head[0].weight.shape[1]
    if not network.wind_inputs or weight.shape[1] != total - WIND_SCALARS:
        raise ValueError(f"{key} has {weight.shape[1]} inputs, expected {total - WIND_SCALARS}")
    at = network.features_before_target - network.num_scalars + 1  # after the budget
    zeros = weight.new_zeros((weight.shape[0], WIND_SCALARS))
    return {**state, key: torch.cat([weight[:, :at], zeros, weight[:, at:]], dim=1)}


def num_scalars(wind_inputs: bool, home_input: bool) -> int:
    """Width of the scalar inputs: the budget, 3 for the wind, 1 for the moves home."""
    return 1 + WIND_SCALARS * bool(wind_inputs) + bool(home_input)


def check_network_kwargs(
    kwargs: object, ranges: dict, label: str, flags: tuple[str, ...] = INPUT_FLAGS
) -> str | None:
    """None if ``kwargs`` are integers within ``ranges`` (each present) and optional bools
    :data:`INPUT_FLAGS`, else what is wrong (``label`` names the network). A file without a
    flag is from before it: the input is off."""
    if not isinstance(kwargs, dict):
        return f"network_kwargs {kwargs!r} are not a dict"
    unknown = set(kwargs) - set(ranges) - set(flags)
    if unknown:
        return f"unknown network_kwargs {sorted(unknown)} for the {label} network"
    for name, (low, high) in ranges.items():
        value = kwargs.get(name)
        if type(value) is not int or not low <= value <= high:
            return f"network_kwargs {name}={value!r} is not an integer in {low}..{high}"
    for flag in flags:
        if type(kwargs.get(flag, False)) is not bool:
            return f"network_kwargs {flag}={kwargs[flag]!r} is not a bool"
    return None
