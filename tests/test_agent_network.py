"""The paper's Q-network: shape, parameter count (Table I) and the one-padded no-fly channel."""

import numpy as np
import pytest
import torch

from cpp_mujoco.agent.network import NFZ_CHANNEL, QNetwork, count_parameters, observation_to_tensors


def test_parameter_count_matches_paper_table_1():
    assert count_parameters(QNetwork(16, 16)) == 1_190_389


@pytest.mark.parametrize("shape", [(16, 16), (8, 12), (20, 7)])
def test_output_shape_any_map_size(shape):
    net = QNetwork(*shape)
    q = net(torch.zeros(3, 5, *shape), torch.ones(3, 1))
    assert q.shape == (3, 5)


def test_conv_layers_keep_shape():
    net = QNetwork(16, 16)
    x = net.pad_input(torch.zeros(2, 5, 16, 16))
    assert x.shape == (2, 5, 20, 20)
    assert net.conv2(net.conv1(x)).shape == (2, 16, 16, 16)


def test_first_layer_pads_only_nfz_with_ones():
    net = QNetwork(6, 6)
    with torch.no_grad():
        net.conv1.weight.zero_()
        net.conv1.bias.zero_()
        for c in range(5):  # filter c sums input channel c over its 5x5 window
            net.conv1.weight[c, c] = 1.0
        out = net.conv1(net.pad_input(torch.zeros(1, 5, 6, 6)))[0]
    for c in range(5):
        if c != NFZ_CHANNEL:
            assert torch.all(out[c] == 0), f"channel {c} must be zero-padded"
    nfz = out[NFZ_CHANNEL]
    assert nfz[0, 0] == 25 - 9  # corner: 16 of 25 window cells are outside
    assert nfz[0, 3] == 10  # top edge: two outside rows
    assert nfz[1, 1] == 25 - 16  # one outside ring
    assert torch.all(nfz[2:4, 2:4] == 0)  # interior windows see no padding


def test_second_layer_is_zero_padded():
    net = QNetwork(6, 6)
    assert net.conv2.padding == (2, 2) and net.conv2.padding_mode == "zeros"


def test_observation_to_tensors_channel_order():
    obs = {
        "map": np.stack([np.eye(4), np.ones((4, 4)), np.zeros((4, 4))]).astype(np.int8)[None],
        "coverage": np.zeros((1, 4, 4), np.int8),
        "position": np.zeros((1, 4, 4), np.int8),
        "budget": np.array([[30.0]], np.float32),
    }
    obs["position"][0, 2, 3] = 1
    grid, budget = observation_to_tensors(obs, budget_scale=75.0)
    assert grid.shape == (1, 5, 4, 4) and grid.dtype == torch.float32
    assert (
        torch.equal(grid[0, 0], torch.eye(4)) and grid[0, 1].sum() == 16 and grid[0, 4, 2, 3] == 1
    )
    assert budget.item() == pytest.approx(30 / 75)  # the scale is a parameter
