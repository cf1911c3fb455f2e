"""The per-map table of the general network's views gives the full computation's numbers bit
for bit (views, their layout, Q-values), and steps aside where it cannot."""

import pytest
import torch

import cpp_mujoco.agent.centred_views as centred_views_module
from cpp_mujoco.agent.centred_views import MIN_TABLE_ROWS, MapViewCache, centred_views
from cpp_mujoco.agent.general_network import GeneralQNetwork
from cpp_mujoco.agent.network import COVERAGE_CHANNEL, POSITION_CHANNEL

SIZES = (32, 17, 21)  # canvas side, local view, global view: the bundled network's


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """A shared 2-core machine: one torch thread."""


def _batch(rows: int, size: int, channels: int = 5, seed: int = 0) -> torch.Tensor:
    """``rows`` observations of one random 0/1 map: each its own coverage and UAV cell."""
    gen = torch.Generator().manual_seed(seed)
    layers = (torch.rand(channels, size, size, generator=gen) < 0.3).float()
    grid = layers.expand(rows, channels, size, size).clone()
    grid[:, COVERAGE_CHANNEL] = (torch.rand(rows, size, size, generator=gen) < 0.5).float()
    grid[:, POSITION_CHANNEL] = 0.0
    cell = torch.randint(size * size, (rows,), generator=gen)
    grid[:, POSITION_CHANNEL].view(rows, -1)[torch.arange(rows), cell] = 1.0
    return grid


def _assert_same(got, want) -> None:
    for a, b in zip(got, want, strict=True):
        assert torch.equal(a, b) and a.stride() == b.stride()


@pytest.mark.parametrize("size,channels", [(16, 5), (32, 5), (32, 6), (20, 6)])
def test_table_views_equal_the_full_views_bit_for_bit(size, channels):
    cache = MapViewCache(*SIZES)
    grid = _batch(MIN_TABLE_ROWS + 7, size, channels)
    _assert_same(cache.views(grid), centred_views(grid, *SIZES))
    assert cache.layers is not None  # served from the table
    other = _batch(MIN_TABLE_ROWS, size, channels, seed=1)  # another map: a new table
    _assert_same(cache.views(other), centred_views(other, *SIZES))
    assert torch.equal(cache.layers[0], other[0, 0])


def test_batches_the_table_cannot_serve_are_computed_in_full():
    cache = MapViewCache(*SIZES)
    mixed = torch.cat([_batch(20, 16), _batch(20, 16, seed=1)])  # two maps
    _assert_same(cache.views(mixed), centred_views(mixed, *SIZES))
    small = _batch(MIN_TABLE_ROWS - 1, 16)
    _assert_same(cache.views(small), centred_views(small, *SIZES))
    blurred = _batch(MIN_TABLE_ROWS, 16)
    blurred[0, POSITION_CHANNEL] *= 0.5  # not one-hot: the table would place a whole UAV
    blurred[0, POSITION_CHANNEL, 0, 0] += 0.5
    _assert_same(cache.views(blurred), centred_views(blurred, *SIZES))
    assert cache.layers is None  # none of them built a table


def test_network_q_values_with_the_table_equal_those_without(monkeypatch):
    torch.manual_seed(0)
    net = GeneralQNetwork(target_input=True)
    grid = _batch(MIN_TABLE_ROWS * 2, 32)
    scalars = torch.rand(grid.shape[0], net.num_scalars)
    with torch.no_grad():
        with_table = net(grid, scalars)
        assert net.view_cache is not None and net.view_cache.layers is not None
        monkeypatch.setattr(centred_views_module, "MIN_TABLE_ROWS", grid.shape[0] + 1)
        net.view_cache = None
        without = net(grid, scalars)
        assert net.view_cache.layers is None  # computed in full
    assert torch.equal(with_table, without)
