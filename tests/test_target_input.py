"""The general network's "moves to new targets" input (``--target-input``): the search inside the
forward pass against the map graph's own distances, padding that changes nothing, and a network
widened with it that flies exactly as before until training teaches it to read the new inputs."""

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from cpp_mujoco.agent import CheckpointError, load_agent
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_network import GeneralQNetwork, pad_grids
from cpp_mujoco.agent.general_training import general_parts, initial_general_weights
from cpp_mujoco.agent.network import observation_to_tensors
from cpp_mujoco.agent.obstacle_input import _square
from cpp_mujoco.agent.target_input import (
    _search_bits,
    _search_cells,
    moves_to_unseen,
    widen_for_target_input,
)
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.graph import graph_from_observation
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.protocol.evaluate import evaluate

from .test_general_agent import SMALL_NET, TINY

CAP = 64


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """Small nets on a shared 2-core machine: one torch thread."""


def _mid_flight(size: int, seed: int, n: int = 40, steps: int = 12) -> dict:
    """Observations of n episodes after ``steps`` random actions (some coverage, many cells)."""
    mdp = GridMDP(generate_from_seed(seed, size), n, size_config(size))
    rng = np.random.default_rng(seed)
    mdp.reset(rng)
    for _ in range(steps):
        mdp.step(rng.integers(0, LAND, n))
    return mdp.observation()


def _reference(obs: dict) -> np.ndarray:
    """The same numbers from the map graph the planners use: its all-pairs distances from each
    asked cell to the cells that see an unseen target (``new_targets_seen`` > 0)."""
    g = graph_from_observation(obs)
    n, h, w = obs["position"].shape
    pos = obs["position"].reshape(n, -1).argmax(axis=1)
    out = np.zeros((n, 5))
    for i in range(n):  # a reference, not a hot path
        unseen = ~obs["coverage"][i].reshape(-1).astype(bool) & g.grid_map.target.reshape(-1)
        useful = np.flatnonzero(g.new_targets_seen(unseen[None])[0] > 0)
        cells = list(g.safety.next_cell[pos[i], :LAND]) + [pos[i]]
        dist = g.distance_from(np.array(cells))[:, useful] if useful.size else np.full((5, 1), CAP)
        best = np.minimum(dist.min(axis=1), CAP).astype(float)
        best[:LAND] += 1  # the move itself
        out[i] = np.minimum(best / CAP, 1.0)
    return out


@pytest.mark.parametrize("size, seed", [(16, 3), (16, 11), (32, 5)])
def test_the_search_gives_the_map_graphs_distances(size, seed):
    obs = _mid_flight(size, seed)
    grid, _ = observation_to_tensors(obs, 75.0)
    got = moves_to_unseen(grid, CAP).numpy()
    assert np.allclose(got, _reference(obs), atol=1e-6)
    assert (got < 1).any() and (got[:, :LAND] >= 1 / CAP).all()  # a move costs at least one
    padded = torch.as_tensor(pad_grids(grid.numpy(), 40))  # no-fly padding changes nothing
    assert torch.equal(moves_to_unseen(padded, CAP), moves_to_unseen(grid, CAP))


def test_the_bit_search_and_the_cell_search_agree():
    rng = np.random.default_rng(0)
    for w in (5, 16, 33, 62):
        free = torch.as_tensor(rng.random((6, 9, w)) < 0.7)
        start = torch.as_tensor(rng.random((6, 9, w)) < 0.05) & free
        q_row = torch.as_tensor(rng.integers(0, 9, (6, 5)))
        q_col = torch.as_tensor(rng.integers(0, w, (6, 5)))
        bits = _search_bits(start, free, q_row, q_col, 20)
        assert torch.equal(bits, _search_cells(start, free, q_row, q_col, 20)), w
        assert (bits == 20).any() and (bits < 20).any()  # both unreachable and found cells


@pytest.mark.parametrize("shape, side", [((7, 16, 16), 3), ((5, 32, 32), 3), ((4, 9, 13), 5)])
def test_the_square_of_unseen_cells_is_the_max_pool_it_replaces(shape, side):
    unseen = torch.as_tensor(np.random.default_rng(side).random(shape) < 0.08)
    pool = F.max_pool2d(unseen[:, None].float(), side, stride=1, padding=side // 2)[:, 0] > 0
    got = _square(unseen, side)
    assert torch.equal(got, pool) and got.any() and not got.all()


def test_a_widened_network_flies_as_before_and_the_option_is_checked(tmp_path):
    plain = GeneralQNetwork(**SMALL_NET, home_input=True)
    wide = GeneralQNetwork(**SMALL_NET, home_input=True, target_input=True)
    wide.load_state_dict(widen_for_target_input(plain.state_dict(), wide.features_before_target))
    obs = _mid_flight(16, 3, n=8)
    grid, scalars = observation_to_tensors(obs, 75.0, home_input=True)
    with torch.no_grad():
        assert torch.equal(wide(grid, scalars), plain(grid, scalars))
    assert wide.kwargs["target_input"] and "target_input" not in plain.kwargs  # old files rebuild
    with pytest.raises(ValueError, match="expected"):
        widen_for_target_input(wide.state_dict(), wide.features_before_target)
    with pytest.raises(ValueError, match="target_input"):
        GeneralTrainConfig(architecture="fcn", target_input=True)


def test_a_run_with_the_input_starts_from_a_network_without_it(tmp_path):
    first = Trainer(GeneralTrainConfig(total_updates=10, **{**TINY, "learning_starts": 64}),
                           tmp_path / "plain")  # fmt: skip
    first.run(progress=False)
    options = {**TINY, "learning_starts": 64, "target_input": True}
    config = GeneralTrainConfig(total_updates=10, init_from=str(tmp_path / "plain/agent.pt"),
                                **options)  # fmt: skip
    init = initial_general_weights(config)
    trainer = Trainer(config, tmp_path / "wide", general_parts(config, init))
    obs = trainer.obs
    before = first.agent().act(obs)
    assert np.array_equal(trainer.agent().act(obs), before)  # zero weights: the same policy
    trainer.run(progress=False)
    agent = load_agent(tmp_path / "wide/agent.pt")
    assert agent.network.target_input and agent.metadata["config"]["target_input"]
    result = evaluate(
        agent, trainer.maps.pool.maps[0], budgets=[25], config=trainer.maps.pool.configs[0]
    )
    assert result.conditions["policy"]["network"]["target_input"]  # results say which inputs
    # a file with the input cannot start a run without it
    back = GeneralTrainConfig(init_from=str(tmp_path / "wide/agent.pt"), **TINY)
    with pytest.raises(CheckpointError, match="needs this run's network"):
        initial_general_weights(back)
