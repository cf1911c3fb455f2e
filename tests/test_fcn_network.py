"""The fully convolutional general network (``--architecture fcn``): any map size, a padded map
gives the map's own Q-values, checkpoints rebuild it, and it trains with the general trainer."""

import numpy as np
import pytest
import torch

from cpp_mujoco.agent import CheckpointError, load_agent
from cpp_mujoco.agent.checkpoint import agent_payload, atomic_save, load_checkpoint
from cpp_mujoco.agent.fcn_network import FCNQNetwork, dilations_for, map_mask
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_network import GeneralQNetwork, pad_grids
from cpp_mujoco.agent.general_training import check_general_resumable
from cpp_mujoco.agent.network import observation_to_tensors
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.map_sets.size_classes import size_config

SMALL_FCN = dict(conv_filters=8, hidden=32, num_hidden=2)


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """Small nets on a shared 2-core machine: one torch thread."""


def _tensors(
    size: int, seed: int, n: int = 6, steps: int = 6, wind: bool = False, home: bool = False
):
    """A batch of mid-episode observations on a generated map (some coverage)."""
    mdp = GridMDP(generate_from_seed(seed, size), n, size_config(size))
    mdp.reset(np.random.default_rng(seed))
    rng = np.random.default_rng(seed + 1)
    for _ in range(steps):
        mdp.step(rng.integers(4, size=n))
    obs = mdp.observation()
    if wind:
        obs["wind"] = rng.normal(size=(n, 2)).astype(np.float32)
    return observation_to_tensors(obs, 75.0, wind_inputs=wind, home_input=home)


# ------------------------------------------------------------------------------------ network
@pytest.mark.parametrize("wind", [False, True])
def test_one_network_for_16_and_32(wind):
    torch.manual_seed(0)
    net = FCNQNetwork(wind_inputs=wind)
    for size in (16, 32):
        grid, scalars = _tensors(size, 3, wind=wind)
        q = net(grid, scalars)
        assert q.shape == (6, 5) and torch.isfinite(q).all()
    assert net.any_size and net.input_cells((32, 32)) == 1024
    # the features at the UAV's cell see the whole 32×32 map from any cell
    assert dilations_for(32) == (1, 2, 4, 8) and net.reach >= 31
    assert FCNQNetwork(max_side=64).reach >= 63


def _padded(grid: torch.Tensor, side: int) -> torch.Tensor:
    return torch.from_numpy(pad_grids(grid.numpy(), side))


def test_a_padded_map_gives_the_maps_own_q_values():
    torch.manual_seed(1)
    net = FCNQNetwork()
    grid, scalars = _tensors(16, 4)
    q = net(grid, scalars)
    for side in (32, 37):  # as the trainer's minibatches, and an odd side
        torch.testing.assert_close(net(_padded(grid, side), scalars), q, rtol=0, atol=1e-6)
    # a mixed minibatch: padded 16×16 rows beside 32×32 rows, as MapPool.grids stacks them
    big, big_scalars = _tensors(32, 5)
    both = net(torch.cat([_padded(grid, 32), big]), torch.cat([scalars, big_scalars]))
    torch.testing.assert_close(both, torch.cat([q, net(big, big_scalars)]), rtol=0, atol=1e-6)


def test_padding_changes_nothing_on_odd_and_non_square_maps():
    torch.manual_seed(2)
    net = FCNQNetwork()
    grid, scalars = _tensors(16, 6)
    grid = grid[:, :, :15, :13].clone()  # odd sides: the half-resolution layers pad a zero row
    grid[:, 3:] = 0.0
    k = torch.arange(6)
    grid[k, 4, k * 2 % 15, k * 3 % 13] = 1.0  # the UAV somewhere on the crop
    want = net(grid, scalars)
    torch.testing.assert_close(net(_padded(grid, 32), scalars), want, rtol=0, atol=1e-6)


def test_the_mask_is_the_maps_extent():
    grid = torch.zeros(1, 5, 10, 12)
    grid[:, 2] = 1.0  # all no-fly but for …
    grid[0, 1, 7, 2] = 1.0  # … a target + no-fly cell (yellow): the last row used
    grid[0, 0, 3, 9] = grid[0, 4, 3, 9] = 1.0  # the UAV on a landing cell: the last column
    grid[0, 2, 3, 9] = 0.0
    want = torch.zeros(1, 1, 10, 12)
    want[..., :8, :10] = 1.0  # plain no-fly rows and columns after them count as outside
    assert torch.equal(map_mask(grid), want)
    padded = map_mask(_padded(grid, 16))
    assert padded.shape == (1, 1, 16, 16) and padded.sum() == 80
    assert torch.equal(padded[..., :10, :12], want)


def test_parameters_and_cost_stay_near_the_global_local_network():
    from cpp_mujoco.agent.network import count_parameters

    fcn, general = count_parameters(FCNQNetwork()), count_parameters(GeneralQNetwork())
    assert fcn == 159_277 and general == 1_174_245  # the report's figures


# --------------------------------------------------------------------------------- checkpoints
def test_checkpoint_round_trip_gives_the_same_q_values(tmp_path):
    torch.manual_seed(3)
    net = FCNQNetwork(**SMALL_FCN, wind_inputs=True)
    payload = agent_payload(net, budget_scale=150.0, map_name="generated", config={})
    assert payload["architecture"] == "general-fcn"
    atomic_save(payload, tmp_path / "fcn.pt")
    agent = load_agent(tmp_path / "fcn.pt")
    assert isinstance(agent.network, FCNQNetwork) and agent.map_shape is None
    assert agent.metadata["architecture"] == "general-fcn"
    assert agent.network.kwargs == net.kwargs
    net.eval()
    for size in (16, 32):
        grid, scalars = _tensors(size, 8, wind=True)
        assert torch.equal(agent.network(grid, scalars), net(grid, scalars))
    assert load_checkpoint(tmp_path / "fcn.pt", map_shape=(20, 20))  # any size


def test_unknown_or_corrupt_architectures_are_clear_errors(tmp_path):
    with pytest.raises(ValueError, match="architecture must be one of global-local, fcn"):
        GeneralTrainConfig(architecture="transformer")
    with pytest.raises(ValueError, match="conv_filters must be >= 2 for fcn"):
        GeneralTrainConfig(architecture="fcn", conv_filters=1)
    good = agent_payload(FCNQNetwork(**SMALL_FCN), budget_scale=75.0, map_name="g", config={})
    kwargs = good["network_kwargs"]
    for change, match in [
        ({"architecture": "transformer"}, "unknown network architecture 'transformer'"),
        ({"architecture": ["general-fcn"]}, "unknown network architecture"),
        ({"network_kwargs": {**kwargs, "local_size": 17}}, "unknown network_kwargs"),
        ({"network_kwargs": {**kwargs, "conv_filters": 1}}, "conv_filters"),
        ({"network_kwargs": {**kwargs, "hidden": 64}}, "do not fit"),
        ({"architecture": "general"}, "unknown network_kwargs|local_size"),
    ]:
        path = tmp_path / "bad.pt"
        atomic_save({**good, **change}, path)
        with pytest.raises(CheckpointError, match=match):
            load_agent(path)


def test_cli_option_selects_the_network():
    from cpp_mujoco.cli.main import build_parser
    from cpp_mujoco.cli.train_general import config_from_args, resume_command

    parser = build_parser()
    args = parser.parse_args(["train-general", "--out", "x", "--architecture", "fcn"])
    config = config_from_args(args)
    assert config.architecture == "fcn" and "--architecture fcn" in resume_command(args)
    assert set(config.network_kwargs()) == {
        "conv_filters", "hidden", "num_hidden", "max_side", "home_input", "wind_inputs"
    }  # fmt: skip
    assert not config.network_kwargs()["wind_inputs"]  # only with --wind-max-speed
    assert config.home_input and config.network_kwargs()["home_input"]  # on for new runs
    off = config_from_args(
        parser.parse_args(["train-general", "--out", "x", "--set", "home_input=false"])
    )
    assert not off.home_input and "--set", "home_input=false" in resume_command(
        parser.parse_args(["train-general", "--out", "x", "--set", "home_input=false"])
    )
    assert GeneralTrainConfig().architecture == "global-local"
    with pytest.raises(SystemExit):
        parser.parse_args(["train-general", "--out", "x", "--architecture", "cnn"])


# ------------------------------------------------------------------------------- training
SMOKE = dict(
    architecture="fcn", sizes=(12, 16), maps_per_size=2, val_maps_per_size=1,
    demo_fraction=0.0, demo_maps_per_size=0, num_envs=8, learning_starts=64, batch_size=32,
    lr_warmup_updates=5, eval_every=10**9, checkpoint_every=10**9, final_eval=False, threads=1,
    guide_updates=20, buffer_size=2_000, checkpoint_minutes=0, eval_budget_step=25,
    total_updates=20, **SMALL_FCN,
)  # fmt: skip


def test_smoke_training_saves_an_fcn_agent(tmp_path):
    # 12×12 maps padded to 16×16 share the minibatches with 16×16 ones
    trainer = Trainer(GeneralTrainConfig(**SMOKE), tmp_path)
    assert isinstance(trainer.online, FCNQNetwork) and trainer.maps.pool.side == 16
    trainer.run(progress=False)
    assert trainer.updates == 20
    agent = load_agent(tmp_path / "agent.pt")
    assert isinstance(agent.network, FCNQNetwork)
    assert agent.network.kwargs == trainer.online.kwargs and agent.network.home_input
    grid, scalars = _tensors(16, 9, home=True)
    trainer.online.eval()
    assert torch.equal(agent.network(grid, scalars), trainer.online(grid, scalars))
    state = load_checkpoint(tmp_path / "checkpoint.pt")
    assert state["config"]["architecture"] == "fcn"
    check_general_resumable(tmp_path / "checkpoint.pt", state, trainer.config, trainer.maps.pool)
    other = GeneralTrainConfig(**{**SMOKE, "architecture": "global-local"})
    with pytest.raises(CheckpointError, match="--architecture fcn"):
        check_general_resumable(tmp_path / "checkpoint.pt", state, other, trainer.maps.pool)
