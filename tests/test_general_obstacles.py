"""The general agent on maps with obstacles (``obstacle_input``): the network reads the obstacle
layer as one more channel, the bundled agent (which reads none) acts bit for bit as before, a
pool of city maps carries its obstacles into the env, the replay and a smoke run whose agent
fits city maps, and the moves to new targets and the finish and revisit masks see what the
grid's camera sees: nothing hidden behind a building."""

import numpy as np
import pytest
import torch

from cpp_mujoco.agent import GENERAL_AGENT, MapSizeError, load_agent
from cpp_mujoco.agent.checkpoint import agent_payload, atomic_save
from cpp_mujoco.agent.fcn_network import FCNQNetwork
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_network import GeneralQNetwork, pad_grids
from cpp_mujoco.agent.general_training import initial_general_weights, training_pool
from cpp_mujoco.agent.map_pool import MapPool, MapwiseGuide
from cpp_mujoco.agent.multi_map_env import MultiMapVectorEnv
from cpp_mujoco.agent.multi_map_replay import MultiMapReplay
from cpp_mujoco.agent.network import OBSTACLE_CHANNEL, observation_to_tensors
from cpp_mujoco.agent.obstacle_input import _extent, targets_in_view, used_cells, view_valid
from cpp_mujoco.agent.policy import GreedyAgent
from cpp_mujoco.agent.rules.finish_mask import finish_allowed, targets_in_reach
from cpp_mujoco.agent.rules.revisit_mask import RevisitMemory
from cpp_mujoco.agent.target_input import moves_to_unseen
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.grid.actions import LAND
from cpp_mujoco.grid.coverage import view_cells
from cpp_mujoco.grid.graph import graph_from_observation
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.maps import load_map
from cpp_mujoco.planners import make_planner

from .hand_observations import hand_observation
from .test_general_agent import SMALL_NET, TINY
from .test_target_input import _reference

CAP = 64
EAST, WEST = 1, 3  # grid.actions.MOVES: north, east, south, west


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """Small nets on a shared 2-core machine: one torch thread."""


def _city_flight(size: int, seed: int, n: int = 12, steps: int = 10) -> dict:
    """Observations on a city map after ``steps`` random moves (some coverage, many cells)."""
    mdp = GridMDP(generate_from_seed(seed, size, family="city"), n, size_config(size))
    rng = np.random.default_rng(seed)
    mdp.reset(rng)
    for _ in range(steps):
        mdp.step(rng.integers(0, LAND, n))
    return mdp.observation()


def _networks() -> list:
    return [
        GeneralQNetwork(**SMALL_NET, home_input=True, target_input=True, obstacle_input=True),
        FCNQNetwork(conv_filters=8, hidden=64, num_hidden=2, home_input=True, obstacle_input=True),
    ]


# ------------------------------------------------------------------------------------ network
@pytest.mark.parametrize("net", _networks(), ids=["global-local", "fcn"])
def test_the_network_reads_the_obstacle_channel_and_records_it(net):
    obs = _city_flight(16, 3)
    assert obs["obstacle"].any()
    grid, scalars = observation_to_tensors(obs, 75.0, home_input=True, obstacle_input=True)
    assert grid.shape[1] == OBSTACLE_CHANNEL + 1
    assert torch.equal(
        grid[:, OBSTACLE_CHANNEL], torch.as_tensor(np.array(obs["obstacle"])).float()
    )
    moved = {**obs, "obstacle": np.roll(obs["obstacle"], 1, axis=2)}  # only the layer changes
    other, same = observation_to_tensors(moved, 75.0, home_input=True, obstacle_input=True)
    with torch.no_grad():
        q, q_moved = net(grid, scalars), net(other, same)
        assert not torch.allclose(q, q_moved)
        # the padding a pool adds (no-fly, obstacle 0) still changes nothing
        padded = torch.as_tensor(pad_grids(grid.numpy(), 32))
        assert torch.allclose(net(padded, scalars), q, atol=1e-6)
    assert net.kwargs["obstacle_input"] is True
    agent = GreedyAgent(net, 75.0)
    assert agent.reads_obstacles and agent.fits(generate_from_seed(3, 16, family="city")) is None
    assert agent.q_values(obs).shape == (12, 5)
    assert agent.act({k: v[4] for k, v in obs.items()}) == agent.act(obs)[4]
    # a map without obstacles: its observation has no layer, the channel reads zeros
    plain = GridMDP(generate_from_seed(3, 16), 2, size_config(16))
    plain.reset(np.random.default_rng(0))
    assert "obstacle" not in plain.observation() and agent.act(plain.observation()).shape == (2,)


def test_a_network_without_the_channel_refuses_obstacles_and_rebuilds_as_before():
    plain = GeneralQNetwork(**SMALL_NET, home_input=True)
    assert "obstacle_input" not in plain.kwargs  # files from before the option rebuild as they were
    agent = GreedyAgent(plain, 75.0)
    city = generate_from_seed(3, 16, family="city")
    assert not agent.reads_obstacles and "obstacle" in agent.fits(city)
    with pytest.raises(MapSizeError, match="obstacle"):
        agent.act(_city_flight(16, 3))
    assert "obstacle_input" not in FCNQNetwork(conv_filters=8).kwargs


# the bundled general agent's Q-values on map A, four episodes of seed 7 after five moves drawn
# from seed 3, recorded before the obstacle input existed (one torch thread); equal within 1e-5:
# torch's CPU kernels differ in the last bits between processors (measured: 1e-6 apart), while
# any change to the network's inputs or layers moves them by far more
BUNDLED_Q = [
    [6.844454765319824, 6.13851261138916, 5.161345481872559, 5.955361843109131,
     -0.05613020062446594],
    [8.2149658203125, 7.130492210388184, 6.485214710235596, 7.323160648345947,
     0.591961145401001],
    [2.6037416458129883, 2.7122745513916016, 1.8223117589950562, 1.9748629331588745,
     -2.3542442321777344],
    [10.65551471710205, 9.905247688293457, 8.593936920166016, 9.850996017456055,
     -0.014809936285018921],
]  # fmt: skip


def test_the_bundled_general_agent_acts_as_before():
    agent = load_agent(GENERAL_AGENT)
    assert not agent.reads_obstacles and "obstacle_input" not in agent.network.kwargs
    mdp = GridMDP(load_map("A"), 4, size_config(16))
    mdp.reset(np.random.default_rng(7))
    rng = np.random.default_rng(3)
    for _ in range(5):
        mdp.step(rng.integers(0, 4, size=4))
    q = agent.q_values(mdp.observation())
    np.testing.assert_allclose(q, np.array(BUNDLED_Q, dtype=np.float32), rtol=0, atol=1e-5)
    assert agent.act(mdp.observation()).tolist() == [0, 0, 1, 0]


def test_init_from_a_network_without_the_channel_starts_from_its_q_values(tmp_path):
    """``--init-from`` the bundled agent with ``obstacle_input``: a zero-weight channel, so on a
    map without obstacles the run starts from the bundled agent's very Q-values."""
    config = GeneralTrainConfig(
        init_from=str(load_agent(GENERAL_AGENT).metadata["source"]), target_input=True,
        obstacle_input=True, map_family="city",
    )  # fmt: skip
    net = GeneralQNetwork(**config.network_kwargs())
    net.load_state_dict(initial_general_weights(config))
    bundled = load_agent(GENERAL_AGENT)
    widened = GreedyAgent(net, bundled.budget_scale)
    mdp = GridMDP(load_map("A"), 4, size_config(16))
    mdp.reset(np.random.default_rng(7))
    obs = mdp.observation()
    assert np.allclose(widened.q_values(obs), bundled.q_values(obs), atol=1e-5)
    fcn = FCNQNetwork(conv_filters=8, hidden=64, num_hidden=2)
    atomic_save(
        agent_payload(fcn, budget_scale=75.0, map_name="generated", config={}),
        tmp_path / "fcn.pt",
    )
    fcn_config = GeneralTrainConfig(
        architecture="fcn", conv_filters=8, hidden=64, num_hidden=2, sizes=(16, 32),
        home_input=False, obstacle_input=True, init_from=str(tmp_path / "fcn.pt"),
    )  # fmt: skip
    wide = FCNQNetwork(**fcn_config.network_kwargs())
    wide.load_state_dict(initial_general_weights(fcn_config))
    grid, scalars = observation_to_tensors(obs, 75.0)
    wide_grid, _ = observation_to_tensors(obs, 75.0, obstacle_input=True)
    with torch.no_grad():
        assert torch.allclose(wide(wide_grid, scalars), fcn(grid, scalars), atol=1e-5)


# ------------------------------------------------------------------------ moves to new targets
@pytest.mark.parametrize("size, seed", [(16, 3), (32, 5)])
def test_the_moves_to_new_targets_see_past_obstacles_as_the_grid_does(size, seed):
    obs = _city_flight(size, seed, n=30)
    grid, _ = observation_to_tensors(obs, 75.0, obstacle_input=True)
    got = moves_to_unseen(grid, CAP).numpy()
    assert np.allclose(got, _reference(obs), atol=1e-6)  # the graph with its obstacles
    square, _ = observation_to_tensors(obs, 75.0)  # the square view alone counts hidden targets
    blind = {k: v for k, v in obs.items() if k != "obstacle"}
    assert np.allclose(moves_to_unseen(square, CAP).numpy(), _reference(blind), atol=1e-6)
    assert not np.allclose(_reference(blind), _reference(obs))  # the obstacles hide some
    padded = torch.as_tensor(pad_grids(grid.numpy(), 40))  # read at the map's own extent
    assert torch.equal(moves_to_unseen(padded, CAP), moves_to_unseen(grid, CAP))
    # a grid with the channel on a map without obstacles: the square, bit for bit
    plain = GridMDP(generate_from_seed(seed, size), 4, size_config(size))
    plain.reset(np.random.default_rng(seed))
    five, _ = observation_to_tensors(plain.observation(), 75.0)
    six, _ = observation_to_tensors(plain.observation(), 75.0, obstacle_input=True)
    assert torch.equal(moves_to_unseen(six, CAP), moves_to_unseen(five, CAP))


def test_a_batch_on_one_map_reads_its_view_table_once_and_sees_what_each_row_would(monkeypatch):
    import cpp_mujoco.agent.obstacle_input as obstacle_input

    obs = _city_flight(32, 5, n=30)
    grid, _ = observation_to_tensors(obs, 75.0, obstacle_input=True)
    unseen = grid[:, 1] > 0.5
    other, _ = observation_to_tensors(_city_flight(32, 6, n=4), 75.0, obstacle_input=True)
    obstacle = grid[:, OBSTACLE_CHANNEL] > 0.5
    assert obstacle_input._one_map_valid(grid, obstacle, 3).shape == (1, 9, 32, 32)
    both = torch.cat([grid, other])
    assert obstacle_input._one_map_valid(both, both[:, OBSTACLE_CHANNEL] > 0.5, 3) is None
    padded = torch.as_tensor(pad_grids(grid.numpy(), 40))
    shared = [targets_in_view(g, g[:, 1] > 0.5, 3) for g in (grid, padded, both)]
    with monkeypatch.context() as patch:  # every row its own table, as before
        patch.setattr(obstacle_input, "_one_map_valid", lambda *args: None)
        each = [targets_in_view(g, g[:, 1] > 0.5, 3) for g in (grid, padded, both)]
    assert all(torch.equal(a, b) for a, b in zip(shared, each, strict=True))
    assert shared[0].any() and not torch.equal(shared[0], unseen)


def test_the_view_table_is_the_grids_and_generated_maps_are_read_at_their_extent():
    for size, seed in [(12, 0), (16, 1), (16, 2), (32, 3)]:
        grid_map = generate_from_seed(seed, size, family="city")
        _, valid = view_cells(grid_map, 3)
        assert np.array_equal(view_valid(grid_map.obstacle, 3).reshape(-1, 9), valid)
        pool = MapPool.generate((size,), 1, seed, family="city")
        grid = pool.grids(
            np.zeros(1, dtype=int), np.zeros((1, 128), np.uint8), np.zeros(1, int), True
        )
        padded = torch.as_tensor(pad_grids(grid, 50))
        assert _extent(used_cells(padded)) == [grid_map.shape]


# ------------------------------------------------------------------------------ pool and run
def test_a_city_pool_carries_its_obstacles_to_the_env_replay_and_guide():
    pool = MapPool.generate((12, 16), 2, 0, family="city")
    assert pool.has_obstacles and pool.obstacles.shape == (4, 16, 16)
    assert pool.identity()["generator"] == {"family": "city"}
    for i, grid_map in enumerate(pool.maps):
        h, w = grid_map.shape
        assert np.array_equal(pool.obstacles[i, :h, :w], grid_map.obstacle)
        assert not pool.obstacles[i, h:].any() and not pool.obstacles[i, :, w:].any()
    env = MultiMapVectorEnv(pool, 6)
    obs, _ = env.reset(seed=1)
    assert np.array_equal(obs["obstacle"], pool.obstacles[obs["map_index"]])
    replay = MultiMapReplay(600, 6, pool, n_step=3, gamma=0.95, obstacle_input=True)
    guide = MapwiseGuide(make_planner("safe-greedy"), pool)
    for _ in range(8):
        actions = guide.act(obs)  # the planner reads each map cropped, obstacles included
        nxt, reward, terminated, _, _ = env.step(actions)
        replay.add(obs, actions, reward, terminated)
        obs = nxt
    batch = replay.sample(20, np.random.default_rng(0))
    grid = batch["obs"][0]
    assert grid.shape == (20, 6, 16, 16)
    t, e = np.divmod(np.arange(replay.rows * 6), 6)
    index = replay.map_index[t, e][:8]
    stored = pool.grids(index, replay.coverage[t, e][:8], replay.position[t, e][:8], True)
    assert np.array_equal(stored[:, OBSTACLE_CHANNEL], pool.obstacles[index])
    # a pool without obstacles observes exactly as before
    paper = MultiMapVectorEnv(MapPool.generate((16,), 2, 0), 2)
    assert "obstacle" not in paper.reset(seed=0)[0]


def test_the_config_trains_city_maps_only_with_the_obstacle_input(monkeypatch):
    with pytest.raises(ValueError, match="obstacle_input"):
        GeneralTrainConfig(map_family="city")
    with pytest.raises(ValueError, match="map_family"):
        GeneralTrainConfig(map_family="town")
    with pytest.raises(ValueError, match="door_walls"):
        GeneralTrainConfig(map_family="city", obstacle_input=True, door_walls=0.5)
    config = GeneralTrainConfig(map_family="city", obstacle_input=True)
    assert config.generator_options() == {"family": "city"}
    assert GeneralTrainConfig(door_walls=0.5).generator_options(validation=True) == {}
    assert config.network_kwargs()["obstacle_input"] is True
    assert "obstacle_input" not in GeneralTrainConfig().network_kwargs()
    # a map brought by name that has obstacles needs the input too
    city = generate_from_seed(4, 16, family="city")
    monkeypatch.setattr("cpp_mujoco.agent.general_training.load_map", lambda name: city)
    options = dict(sizes=(16,), maps_per_size=1, named_maps=("site.png",))
    with pytest.raises(ValueError, match="obstacle_input=true"):
        training_pool(GeneralTrainConfig(**options))
    assert len(training_pool(GeneralTrainConfig(obstacle_input=True, **options))) == 2


def test_the_cli_takes_the_family_and_the_input():
    from cpp_mujoco.cli.main import build_parser
    from cpp_mujoco.cli.train_general import config_from_args

    args = build_parser().parse_args(
        ["train-general", "--out", "x", "--set", "obstacle_input=true", "--set",
         "map_family=city"]
    )  # fmt: skip
    config = config_from_args(args)
    assert config.obstacle_input and config.map_family == "city"


def test_a_smoke_run_on_city_maps_makes_an_agent_that_fits_them(tmp_path):
    options = {**TINY, "maps_per_size": 2, "demo_maps_per_size": 2, "learning_starts": 200}
    config = GeneralTrainConfig(
        total_updates=200, map_family="city", obstacle_input=True, target_input=True, **options
    )
    trainer = Trainer(config, tmp_path)
    assert trainer.maps.pool.has_obstacles and "obstacle" in trainer.obs
    assert trainer.demos is not None and trainer.demos.obstacle_input
    trainer.run(progress=False)
    assert trainer.updates == 200
    agent = load_agent(tmp_path / "agent.pt")
    assert agent.reads_obstacles and agent.network.kwargs["obstacle_input"] is True
    assert agent.metadata["config"]["map_family"] == "city"
    city = generate_from_seed(7, 16, family="city")
    assert agent.fits(city) is None
    mdp = GridMDP(city, 3, size_config(16))
    mdp.reset(np.random.default_rng(0))
    assert agent.act(mdp.observation()).shape == (3,)


# ------------------------------------------------------------------------------------ rules
def _behind_a_building(cell=(3, 1), budget=3, **kwargs) -> dict:
    """A 7×7 map: landing (3, 1), the one target (2, 3) diagonal to (3, 2), whose two cells
    between are buildings (obstacle and no-fly): from (3, 2) the target is hidden, and no
    other cell within a budget of 3 has it in its square."""
    buildings = [(2, 2), (3, 3)]
    obs = hand_observation(
        h=7, w=7, cell=cell, budget=budget, targets=[(2, 3)], nfz=buildings,
        landing=[(3, 1)], **kwargs,
    )  # fmt: skip
    obstacle = np.zeros((7, 7), dtype=np.int8)
    for r, c in buildings:
        obstacle[r, c] = 1
    return {**obs, "obstacle": obstacle}


def test_the_finish_mask_counts_no_target_hidden_behind_a_building():
    obs = _behind_a_building()
    graph = graph_from_observation(obs)
    unseen = graph.grid_map.target.reshape(1, -1)
    assert graph.new_targets_seen(unseen)[0, 3 * 7 + 2] == 0  # the grid's own view
    assert targets_in_reach(obs).tolist() == [False]
    blind = {k: v for k, v in obs.items() if k != "obstacle"}  # the square would count it
    assert targets_in_reach(blind).tolist() == [True]
    allowed = np.ones((1, 5), dtype=bool)
    assert finish_allowed(obs, allowed)[0, LAND] and not finish_allowed(blind, allowed)[0, LAND]
    # rows of one map with and without the layer: decided map by map
    both = {k: np.concatenate([v, v]) for k, v in blind.items() if k != "map"}
    both["map"] = np.stack([obs["map"], obs["map"]])
    both["obstacle"] = np.stack([obs["obstacle"], np.zeros_like(obs["obstacle"])])
    assert targets_in_reach(both).tolist() == [False, True]


def test_the_revisit_mask_counts_no_target_hidden_behind_a_building():
    """Flown (3, 1) → (3, 2) → (3, 1) with the coverage unchanged: the move back east into
    (3, 2) is fruitless where the building hides the target, not in the square view."""
    dropped = {}
    for name, keep in (("occluded", True), ("square", False)):
        memory = RevisitMemory()
        for cell, budget in (((3, 2), 9), ((3, 1), 8)):
            obs = _behind_a_building(cell=cell, budget=budget)
            obs = obs if keep else {k: v for k, v in obs.items() if k != "obstacle"}
            allowed = memory.allowed(obs, np.ones((1, 5), dtype=bool))
        dropped[name] = not allowed[0, EAST]
        assert allowed[0, WEST]
    assert dropped == {"occluded": True, "square": False}
