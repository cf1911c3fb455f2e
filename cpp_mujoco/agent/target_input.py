"""The general network's "moves to new targets" input: for each action, how many moves from the
cell it leads to until the camera's view holds a target cell not seen yet.

Why: on maps it has never seen, the masked general agent (which knows its way home) matched the
safe greedy planner on the maps it trained on, but fell 2–3 coverage points behind it on unseen
ones — it flew over seen cells where the planner heads for the nearest unseen target. The planner
knows the distances to every cell; a network reading a 3×3-pooled global view must guess them
through walls and one-cell passages. This input hands it the one distance that matters for
coverage, as :mod:`~cpp_mujoco.agent.home_input` hands it the way home; the network still decides
(it may trade a near target for a richer region, as beam search does).

It is computed inside the network's forward pass from the observation's own channels (map,
coverage, UAV cell), so every path that feeds the network — acting, the replay's minibatches,
demonstrations — gets it without storing anything: a multi-source breadth-first search run as
batched array shifts (one step of every search per iteration, all rows at once) from the cells
whose 3×3 view holds an unseen target, through the cells a move may enter (not no-fly, not off
the map; padding is no-fly, so a padded map gives the same numbers). A grid with the obstacle
channel (:mod:`~cpp_mujoco.agent.obstacle_input`) starts from the cells whose view, less what its
obstacles hide, holds an unseen target: the grid's own view rule, through each map's cached view
table (:func:`~cpp_mujoco.agent.obstacle_input.targets_in_view`).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from cpp_mujoco.agent.network import (
    COVERAGE_CHANNEL,
    NFZ_CHANNEL,
    POSITION_CHANNEL,
    TARGET_CHANNEL,
)
from cpp_mujoco.agent.obstacle_input import targets_in_view
from cpp_mujoco.grid.actions import MOVES
from cpp_mujoco.grid.mdp import GridConfig

FOV_SIDE = GridConfig.fov_side  # the paper's camera footprint: the 3×3 cells around the UAV
NUM_FEATURES = len(MOVES)  # the four moves, then the UAV's own cell


def moves_to_unseen(grid: torch.Tensor, cap: int) -> torch.Tensor:
    """(B,5,H,W) observation grids (or (B,6,H,W), with obstacles) → (B,5) float in [0, 1]: for
    each move (north, east, south, west), 1 + the fewest moves from the cell it leads to (the
    UAV's own if the move is rejected) to a cell whose view holds an unseen target; last, the
    fewest from the UAV's cell. Divided by ``cap`` and clipped at 1 (1 also means no unseen
    target is reachable)."""
    b, _, h, w = grid.shape
    free = grid[:, NFZ_CHANNEL] < 0.5
    unseen = (grid[:, TARGET_CHANNEL] > 0.5) & (grid[:, COVERAGE_CHANNEL] < 0.5)
    sees = targets_in_view(grid, unseen, FOV_SIDE)
    flat = grid[:, POSITION_CHANNEL].reshape(b, -1).argmax(dim=1)
    row, col = flat // w, flat % w
    rows = torch.arange(b, device=grid.device)[:, None]
    # the cells asked about: the cell each move leads to (the UAV's if rejected), then its own
    d_row = torch.as_tensor(MOVES[:, 0], device=grid.device)
    d_col = torch.as_tensor(MOVES[:, 1], device=grid.device)
    r, c = row[:, None] + d_row, col[:, None] + d_col
    inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
    accepted = inside & free[rows, r.clamp(0, h - 1), c.clamp(0, w - 1)]
    q_row, q_col = torch.where(accepted, r, row[:, None]), torch.where(accepted, c, col[:, None])
    search = _search_bits if w <= _WORD_BITS else _search_cells
    steps = search(sees & free, free, q_row, q_col, cap).to(grid.dtype)
    steps[:, :-1] += 1.0
    return (steps / cap).clamp(max=1.0)


_WORD_BITS = 62  # a map row as one int64's bits (shifts stay clear of the sign bit)


def _search_bits(
    start: torch.Tensor, free: torch.Tensor, q_row: torch.Tensor, q_col: torch.Tensor, cap: int
) -> torch.Tensor:
    """(B,Q) fewest moves through ``free`` cells from any ``start`` cell to each asked cell
    (``cap`` if none within ``cap``): the search's front as one int64 bit mask per map row, so
    a step is a few shifts of a (B,H) tensor whatever the map's width."""
    b, h, w = start.shape
    weights = 2 ** torch.arange(w, device=start.device, dtype=torch.int64)
    reached = (start.long() * weights).sum(-1)  # (B, H)
    passable = (free.long() * weights).sum(-1)
    rows = torch.arange(b, device=start.device)[:, None]
    found = torch.full(q_row.shape, cap, dtype=torch.int64, device=start.device)
    for step in range(cap):
        hit = ((reached[rows, q_row] >> q_col) & 1).bool()
        found = torch.where(hit & (found == cap), step, found)
        if bool((found < cap).all()):  # every asked cell reached: the rest changes nothing
            break
        grown = reached | (reached << 1) | (reached >> 1)
        grown[:, 1:] |= reached[:, :-1]
        grown[:, :-1] |= reached[:, 1:]
        grown &= passable  # also drops the bit shifted past the row's last cell
        if torch.equal(grown, reached):
            break
        reached = grown
    return found


def _search_cells(
    start: torch.Tensor, free: torch.Tensor, q_row: torch.Tensor, q_col: torch.Tensor, cap: int
) -> torch.Tensor:
    """:func:`_search_bits` for maps wider than a word: the same search, a float per cell."""
    far = float(cap)
    dist = torch.where(start, 0.0, far)
    rows = torch.arange(start.shape[0], device=start.device)[:, None]
    for _ in range(cap):
        if bool((dist[rows, q_row, q_col] < far).all()):  # a cell's first distance is its last
            break
        padded = F.pad(dist, (1, 1, 1, 1), value=far)
        nearest = torch.minimum(
            torch.minimum(padded[:, :-2, 1:-1], padded[:, 2:, 1:-1]),
            torch.minimum(padded[:, 1:-1, :-2], padded[:, 1:-1, 2:]),
        )
        new = torch.where(free, torch.minimum(dist, nearest + 1.0), far)
        if torch.equal(new, dist):
            break
        dist = new
    return dist[rows, q_row, q_col].long()


def widen_for_target_input(state: dict[str, torch.Tensor], features: int) -> dict:
    """A network's weights without the input → weights with it that give the very same
    Q-values: zero columns for the new inputs (the last ``NUM_FEATURES`` of the first dense
    layer, whose inputs before them are ``features``); training then learns to use them."""
    key = "head.0.weight"
    weight = state[key]
    if weight.shape[1] != features:
        raise ValueError(f"{key} has {weight.shape[1]} inputs, expected {features}")
    zeros = weight.new_zeros((weight.shape[0], NUM_FEATURES))
    return {**state, key: torch.cat([weight, zeros], dim=1)}
