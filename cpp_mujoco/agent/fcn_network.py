"""A fully convolutional Q-network for maps of any size: the alternative to the global-local one.

:class:`~cpp_mujoco.agent.general_network.GeneralQNetwork` hands its dense layers a fixed-size
picture (a crop around the UAV and a pooled view of the map centred on it). This network never
flattens the map: shape-keeping ("same") convolutions compute per-cell features on the map as it
is, which are read twice —

* **pooled**: the max and the mean of every feature over the map's cells (what is anywhere);
* **at the UAV**: the features of the UAV's own cell (what is around it, and in which direction),

then the budget (and the wind, × ``WIND_GAIN``, with ``wind_inputs``; the moves home with
``home_input``, :mod:`~cpp_mujoco.agent.home_input`) is appended and dense layers give the 5
Q-values, as in the other networks. The same weights fit any H×W.

Layers (``conv_filters`` = C): the 5 grid channels (6 with ``obstacle_input``: the obstacle layer,
:mod:`~cpp_mujoco.agent.obstacle_input`) plus three — the in-map mask and each cell's row
and column offset from the UAV ÷ ``max_side`` (pooling forgets where a cell lies; the offsets let
"a target north of the UAV" differ from "a target south of it") — into a 3×3 stem and two residual
3×3 layers at full resolution (C/2 filters: the near field, read at the UAV's cell), a 2×2 stride-2
convolution to C filters, then residual 3×3 layers of dilation 1, 2, 4, … until the features at
the UAV's cell see ``max_side − 1`` cells away in every direction (33 for 32: the whole map from
any cell). Residual layers (``x + relu(conv(x))``) pass the early layers' detail on unchanged.

Why one halving: the same context at full resolution (16 filters, dilations up to 16) costs 15 M
multiply-adds per 32×32 state and took 3.6× (forward) and 7× (forward + backward) the global-local
network's time on a batch of 128; halved, 4.4 M (the global-local's: 4.0 M), 1.6× and 2× (measured
in one process, one CPU thread; on 16×16 maps, 1.2 M and faster than the global-local).

Padding: the trainer stacks 16×16 and 32×32 states in one minibatch by padding the small maps with
plain no-fly cells at the bottom and right (:class:`~cpp_mujoco.agent.map_pool.MapPool`,
:func:`~cpp_mujoco.agent.general_network.pad_grids`), then flies the policy on the maps unpadded;
the padding must change nothing. So the network works on the map's extent only (:func:`map_mask`):
every layer's output is zeroed outside it — the zeros that "same" convolutions pad with outside an
unpadded map — and the pooling counts its cells only. The Q-values of a padded map are those of the
map itself, up to float rounding (the sums run in another order).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from cpp_mujoco.agent.general_network import (
    INPUT_FLAGS,
    OBSTACLE_FLAG,
    check_network_kwargs,
    num_scalars,
)
from cpp_mujoco.agent.network import IN_CHANNELS, POSITION_CHANNEL, dense_head
from cpp_mujoco.agent.obstacle_input import used_cells

ARCHITECTURE = "general-fcn"  # what a checkpoint of this network records under "architecture"
EXTRA_CHANNELS = 3  # in-map mask, row offset, column offset from the UAV
FINE_BLOCKS = 2  # residual 3×3 layers after the stem, at full resolution
FINE_RADIUS = 1 + FINE_BLOCKS  # cells the full-resolution features see in each direction
# network_kwargs a checkpoint may hold: name → (smallest value, largest value)
KWARG_RANGES = {
    "conv_filters": (2, 1024),
    "hidden": (1, 16384),
    "num_hidden": (0, 16),
    "max_side": (1, 512),
}


def dilations_for(max_side: int) -> tuple[int, ...]:
    """Dilations 1, 2, 4, … of the half-resolution layers (at least one), until the features
    at the UAV's cell see ``max_side − 1`` cells away: 2·Σ dilations + :data:`FINE_RADIUS`."""
    dilations = [1]
    while 2 * sum(dilations) + FINE_RADIUS < max_side - 1:
        dilations.append(2 * dilations[-1])
    return tuple(dilations)


class FCNQNetwork(nn.Module):
    """Q(s, ·) for a map of any size. ``forward(grid, scalars)`` as :class:`QNetwork`'s: grid
    (B,5,H,W) float (any H, W; one size per call; (B,6,H,W) with ``obstacle_input``: the
    obstacle layer last, :mod:`~cpp_mujoco.agent.obstacle_input`), scalars
    (B, :attr:`num_scalars`): the scaled budget, then wind with ``wind_inputs`` and the moves
    home with ``home_input`` (:func:`~cpp_mujoco.agent.network.scalar_inputs`)."""

    any_size = True  # GreedyAgent: no map-size check
    grid_layers = ("stem.weight",)  # the layer reading the grid (its channels, then the extras)

    def __init__(
        self,
        conv_filters: int = 16,
        hidden: int = 256,
        num_hidden: int = 3,
        max_side: int = 32,
        wind_inputs: bool = False,
        home_input: bool = False,
        obstacle_input: bool = False,
    ):
        super().__init__()
        if conv_filters < 2:
            raise ValueError(
                f"conv_filters must be >= 2 (C/2 at full resolution), got {conv_filters}"
            )
        self.kwargs = dict(
            conv_filters=conv_filters, hidden=hidden, num_hidden=num_hidden, max_side=max_side,
            wind_inputs=bool(wind_inputs), home_input=bool(home_input),
        )  # fmt: skip
        if obstacle_input:  # recorded only when on: older files rebuild as they were
            self.kwargs[OBSTACLE_FLAG] = True
        self.obstacle_input = bool(obstacle_input)
        self.max_side = max_side
        self.height = self.width = None  # any map size
        self.wind_inputs, self.home_input = bool(wind_inputs), bool(home_input)
        self.num_scalars = num_scalars(self.wind_inputs, self.home_input)
        self.dilations = dilations_for(max_side)
        self.reach = 2 * sum(self.dilations) + FINE_RADIUS  # cells seen from the UAV's cell
        c, fine = conv_filters, conv_filters // 2
        channels = IN_CHANNELS + self.obstacle_input + EXTRA_CHANNELS
        self.stem = nn.Conv2d(channels, fine, 3, padding=1)
        self.fine = nn.ModuleList(nn.Conv2d(fine, fine, 3, padding=1) for _ in range(FINE_BLOCKS))
        self.down = nn.Conv2d(fine, c, 2, stride=2)
        self.coarse = nn.ModuleList(
            nn.Conv2d(c, c, 3, padding=d, dilation=d) for d in self.dilations
        )
        width_in = 3 * c + fine + self.num_scalars  # max, mean, at the UAV ×2; the scalars
        self.head = dense_head(width_in, hidden, num_hidden)

    def input_cells(self, shape: tuple[int, int]) -> int:
        """Cells a forward pass holds per row (GreedyAgent's chunking): the map's own."""
        return shape[0] * shape[1]

    def inputs(self, grid: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(the stem's input (B,8,H,W), or (B,9,H,W) with the obstacle channel; mask (B,1,H,W);
        the UAV's flat cell (B,)). The input is
        laid out channels-last: the convolutions ran 1.3–4× faster on it (measured, one CPU
        thread), so it is built that way (one copy) instead of converted."""
        b, _, h, w = grid.shape
        mask = map_mask(grid)
        cell = grid[:, POSITION_CHANNEL].reshape(b, -1).argmax(dim=1)
        rows = torch.arange(h, device=grid.device, dtype=grid.dtype)
        cols = torch.arange(w, device=grid.device, dtype=grid.dtype)
        dy = (rows[None, :] - (cell // w).to(grid.dtype)[:, None]) / self.max_side  # (B,H)
        dx = (cols[None, :] - (cell % w).to(grid.dtype)[:, None]) / self.max_side  # (B,W)
        on = mask[:, 0]  # (B,H,W)
        parts = [(grid * mask).permute(0, 2, 3, 1), on, dy[:, :, None] * on, dx[:, None] * on]
        x = torch.cat([p if p.dim() == 4 else p[..., None] for p in parts], dim=3)
        return x.permute(0, 3, 1, 2), mask, cell

    def forward(self, grid: torch.Tensor, scalars: torch.Tensor) -> torch.Tensor:
        x, mask, cell = self.inputs(grid)
        h, w = x.shape[-2:]
        fine = _spread(mask, self.stem.out_channels)  # the mask for every channel, laid out as x
        x = self.stem(x).relu_() * fine
        for conv in self.fine:
            x = torch.addcmul(x, conv(x).relu_(), fine)  # x + relu(conv(x)) · mask, one pass
        fine_at_uav = _at(x, cell)
        if h % 2 or w % 2:  # an odd side: a zero row/column first (the zeros outside the map)
            x, mask = F.pad(x, (0, w % 2, 0, h % 2)), F.pad(mask, (0, w % 2, 0, h % 2))
        mask = F.max_pool2d(mask, 2)  # a half cell is on the map if one of its cells is
        coarse = _spread(mask, self.down.out_channels)
        x = self.down(x).relu_() * coarse
        for conv in self.coarse:
            x = torch.addcmul(x, conv(x).relu_(), coarse)
        half_cell = (cell // w // 2) * x.shape[3] + (cell % w) // 2
        flat = x.flatten(2)  # (B,C,cells)
        # features are ≥ 0 (sums of ReLUs) and 0 off the map: the plain max is the map's
        pooled_max = flat.amax(dim=2)
        pooled_mean = flat.sum(dim=2) / mask.flatten(1).sum(dim=1, keepdim=True)
        z = [pooled_max, pooled_mean, _at(x, half_cell), fine_at_uav]
        return self.head(torch.cat([*z, scalars.reshape(-1, self.num_scalars)], dim=1))


def _spread(mask: torch.Tensor, channels: int) -> torch.Tensor:
    """(B,1,H,W) → (B,channels,H,W) channels-last: multiplying a channels-last tensor by the
    broadcast mask took 3× as long as by this copy (measured), and each is used 3–5 times."""
    b, _, h, w = mask.shape
    return mask.permute(0, 2, 3, 1).expand(b, h, w, channels).contiguous().permute(0, 3, 1, 2)


def _at(x: torch.Tensor, cell: torch.Tensor) -> torch.Tensor:
    """(B,C,H,W) features at each row's flat cell → (B,C)."""
    b, c = x.shape[:2]
    return x.flatten(2).gather(2, cell.view(b, 1, 1).expand(b, c, 1)).squeeze(2)


def map_mask(grid: torch.Tensor) -> torch.Tensor:
    """(B,1,H,W) float: 1 on the map's extent, 0 on the padding after it.

    The extent is the top-left rectangle up to the last row and the last column holding a cell
    that is not plain no-fly (no-fly and neither landing, target, the UAV nor — with the obstacle
    channel — an obstacle: :func:`~cpp_mujoco.agent.obstacle_input.used_cells`).
    Padding adds exactly such cells at the bottom and right, so a padded map has the extent of
    the map itself. A map whose own last rows or columns are plain no-fly loses them as well —
    the same to the task: neither can be flown over nor covered (the global-local network sees
    outside the map as no-fly too). Coverage is not read, so the extent holds for an episode."""
    used = used_cells(grid)  # (B,H,W)
    rows = used.any(dim=2).flip(1).cumsum(1).flip(1) > 0  # a used cell in this row or below
    cols = used.any(dim=1).flip(1).cumsum(1).flip(1) > 0
    return (rows[:, :, None] & cols[:, None, :]).unsqueeze(1).to(grid.dtype)


def check_fcn_kwargs(kwargs: object) -> str | None:
    """None if ``kwargs`` can build a :class:`FCNQNetwork`, else what is wrong."""
    return check_network_kwargs(kwargs, KWARG_RANGES, "fcn", (*INPUT_FLAGS, OBSTACLE_FLAG))
