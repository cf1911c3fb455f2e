"""The general network's moves-home input: the BFS moves home of the UAV's cell, the same from
an observation (single or batched, one map or one per row, padded or not) as from the replay,
stored with the network, off for checkpoints and runs from before it."""

from collections import deque

import numpy as np
import pytest
import torch

from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.checkpoint import CheckpointError, agent_payload, atomic_save, load_checkpoint
from cpp_mujoco.agent.fcn_network import FCNQNetwork
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_network import GeneralQNetwork, check_general_kwargs
from cpp_mujoco.agent.home_input import NO_WAY_HOME, home_field, moves_home
from cpp_mujoco.agent.map_pool import MapPool, padded_cell
from cpp_mujoco.agent.multi_map_env import MultiMapVectorEnv
from cpp_mujoco.agent.multi_map_replay import MultiMapReplay
from cpp_mujoco.agent.network import check_can_start_from, observation_to_tensors
from cpp_mujoco.agent.policy import GreedyAgent
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.maps import load_map

SMALL_NET = dict(local_size=9, global_size=11, conv_filters=8, hidden=64, num_hidden=2)
SCALE = 75.0


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """Small nets on a shared 2-core machine: one torch thread."""


def _bfs_moves_home(grid_map) -> np.ndarray:
    """The reference: breadth-first from the landing cells over 4-neighbour moves into cells
    that are not no-fly; -1 where no landing cell is reachable."""
    h, w = grid_map.shape
    dist = np.full((h, w), -1)
    queue = deque()
    for r, c in zip(*np.nonzero(grid_map.landing), strict=True):
        dist[r, c] = 0
        queue.append((r, c))
    while queue:
        r, c = queue.popleft()
        for rr, cc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
            if 0 <= rr < h and 0 <= cc < w and not grid_map.nfz[rr, cc] and dist[rr, cc] < 0:
                dist[rr, cc] = dist[r, c] + 1
                queue.append((rr, cc))
    return dist


def _observation_at(grid_map, cells: list[tuple[int, int]], budget: float = 40.0) -> dict:
    """A batched observation of ``grid_map`` with the UAV on each of ``cells``."""
    h, w = grid_map.shape
    position = np.zeros((len(cells), h, w), dtype=np.int8)
    for i, (r, c) in enumerate(cells):
        position[i, r, c] = 1
    return {
        "map": grid_map.layers.astype(np.int8),
        "coverage": np.zeros((len(cells), h, w), dtype=np.int8),
        "position": position,
        "budget": np.full((len(cells), 1), budget, dtype=np.float32),
    }


def _mid_episode(size: int, seed: int, n: int = 8) -> dict:
    mdp = GridMDP(generate_from_seed(seed, size), n, size_config(size))
    mdp.reset(np.random.default_rng(seed))
    rng = np.random.default_rng(seed + 1)
    for _ in range(7):
        mdp.step(rng.integers(4, size=n))
    return mdp.observation()


# ------------------------------------------------------------------------------- the numbers
def test_moves_home_on_map_a_are_the_bfs_moves():
    a = load_map("A")
    want = _bfs_moves_home(a)
    field = home_field(a.layers).reshape(a.shape)
    flyable = ~a.nfz
    assert np.array_equal(np.where(want >= 0, want, NO_WAY_HOME)[flyable], field[flyable])
    # known cells: on the landing zone, its top-left corner and the far corner
    assert field[10, 0] == 0 and field[0, 0] == 10 and field[0, 15] == 20
    cells = [(10, 0), (0, 0), (0, 15), (5, 7), (15, 13)]
    _, scalars = observation_to_tensors(_observation_at(a, cells), SCALE, home_input=True)
    assert scalars.shape == (5, 2)
    assert torch.equal(scalars[:, 0], torch.full((5,), 40.0 / SCALE))
    home = np.array([want[c] for c in cells], dtype=np.float32) / np.float32(SCALE)
    assert torch.equal(scalars[:, 1], torch.from_numpy(home))
    # without the option: the budget only, as before
    _, plain = observation_to_tensors(_observation_at(a, cells), SCALE)
    assert torch.equal(plain, scalars[:, :1])


def test_single_batched_shared_and_per_row_maps_agree():
    obs = _mid_episode(32, 4)
    assert obs["map"].strides[0] == 0  # GridMDP's one map, broadcast
    shared = {**obs, "map": np.asarray(obs["map"][0])}
    per_row = {**obs, "map": np.ascontiguousarray(obs["map"])}
    want = moves_home(shared["map"], obs["position"])
    assert (want > 0).any()  # the episodes have left the landing zone
    for o in (obs, per_row):
        assert np.array_equal(moves_home(o["map"], o["position"]), want)
    tensors = [observation_to_tensors(o, SCALE, home_input=True)[1] for o in (obs, shared, per_row)]
    assert all(torch.equal(t, tensors[0]) for t in tensors[1:])
    # rows of different maps in one batch, each row its own map's number
    other = _mid_episode(32, 9)
    mixed_maps = np.concatenate([per_row["map"][:4], np.ascontiguousarray(other["map"][:4])])
    mixed_pos = np.concatenate([obs["position"][:4], other["position"][:4]])
    got = moves_home(mixed_maps, mixed_pos)
    assert np.array_equal(got[:4], want[:4])
    assert np.array_equal(got[4:], moves_home(other["map"][0], other["position"][:4]))
    # the policy: one observation acts as its row of the batch
    torch.manual_seed(0)
    agent = GreedyAgent(GeneralQNetwork(**SMALL_NET, home_input=True), SCALE)
    batch_q = agent.q_values(obs)
    for i in range(3):
        single = {k: np.asarray(v[i]) for k, v in obs.items()}
        assert agent.act(single) == int(batch_q[i].argmax())
        assert np.allclose(agent.q_values({k: v[None] for k, v in single.items()}), batch_q[i])


def test_replay_minibatches_read_what_the_policy_reads():
    """The learning path (pool index) and the acting path (observed map, padded or not)."""
    pool = MapPool.generate((16, 32), 2, 0)
    env = MultiMapVectorEnv(pool, num_envs=4)
    replay = MultiMapReplay(400, 4, pool, n_step=2, gamma=0.9)
    rng = np.random.default_rng(0)
    obs, _ = env.reset(seed=2)
    seen = []
    for _ in range(40):
        actions = rng.integers(4, size=4)
        nxt, reward, terminated, _, _ = env.step(actions)
        replay.add(obs, actions, reward, terminated)
        seen.append(obs)
        obs = nxt
    t = rng.integers(replay._valid_rows(), size=100)
    e = rng.integers(4, size=100)
    home = replay.transitions(t, e)["obs"][3]
    acting = np.array([moves_home(seen[r]["map"][[k]], seen[r]["position"][[k]])[0]
                       for r, k in zip(t, e, strict=True)])  # fmt: skip
    assert np.array_equal(home, acting) and (home > 0).any()
    for m in range(len(pool)):  # the pool's padded maps: the maps' own numbers
        own = home_field(pool.maps[m].layers)
        h, w = pool.maps[m].shape
        cells = np.arange(h * w)
        padded = pool.moves_home(np.full(cells.size, m), padded_cell(cells, w, pool.side))
        assert np.array_equal(padded, own)


# ------------------------------------------------------------------------------- the network
@pytest.mark.parametrize("kind", [GeneralQNetwork, FCNQNetwork])
def test_a_home_input_network_saves_loads_and_flies_both_sizes(kind, tmp_path):
    torch.manual_seed(1)
    net = kind(**(SMALL_NET if kind is GeneralQNetwork else {"conv_filters": 8, "hidden": 32}),
               home_input=True)  # fmt: skip
    assert net.home_input and net.num_scalars == 2 and net.kwargs["home_input"] is True
    atomic_save(agent_payload(net, budget_scale=SCALE, map_name="g", config={}), tmp_path / "h.pt")
    agent = load_agent(tmp_path / "h.pt")
    assert agent.network.home_input and agent.network.kwargs == net.kwargs
    net.eval()
    for size in (16, 32):
        obs = _mid_episode(size, 5)
        grid, scalars = observation_to_tensors(obs, SCALE, home_input=True)
        assert torch.equal(agent.network(grid, scalars), net(grid, scalars))
        actions = agent.act(obs)
        assert actions.shape == (8,)
        farther = scalars.clone()
        farther[:, 1] += 0.5
        assert not torch.equal(net(grid, farther), net(grid, scalars))  # the input is read


def test_checkpoints_from_before_the_option_load_without_it(tmp_path):
    torch.manual_seed(2)
    net = GeneralQNetwork(**SMALL_NET)
    payload = agent_payload(net, budget_scale=SCALE, map_name="g", config={})
    del payload["network_kwargs"]["home_input"]  # as every file before the option
    atomic_save(payload, tmp_path / "old.pt")
    agent = load_agent(tmp_path / "old.pt")
    assert not agent.network.home_input and agent.network.num_scalars == 1
    obs = _mid_episode(32, 6)
    assert np.array_equal(agent.q_values(obs), GreedyAgent(net, SCALE).q_values(obs))
    assert check_general_kwargs({**payload["network_kwargs"], "home_input": 1}) is not None
    bad = {**payload, "network_kwargs": {**payload["network_kwargs"], "home_input": "yes"}}
    atomic_save(bad, tmp_path / "bad.pt")
    with pytest.raises(CheckpointError, match="home_input='yes' is not a bool"):
        load_agent(tmp_path / "bad.pt")
    # the weights of a home network do not fit a file that says it has none
    home = agent_payload(GeneralQNetwork(**SMALL_NET, home_input=True), budget_scale=SCALE,
                         map_name="g", config={})  # fmt: skip
    home["network_kwargs"]["home_input"] = False
    atomic_save(home, tmp_path / "mixed.pt")
    with pytest.raises(CheckpointError, match="do not fit"):
        load_agent(tmp_path / "mixed.pt")
    # a per-map run cannot start from a general network, home input or not
    with pytest.raises(ValueError, match="general network"):
        check_can_start_from(GeneralQNetwork(**SMALL_NET, home_input=True), 16, 16, False)


# ------------------------------------------------------------------------------- runs
RUN = dict(
    sizes=(16,), maps_per_size=2, val_maps_per_size=1, demo_fraction=0.0, demo_maps_per_size=0,
    num_envs=8, learning_starts=64, batch_size=32, lr_warmup_updates=5, eval_every=10**9,
    checkpoint_every=10**9, final_eval=False, threads=1, guide_updates=10, buffer_size=2_000,
    checkpoint_minutes=0, eval_budget_step=25, **SMALL_NET,
)  # fmt: skip


def test_runs_from_before_the_option_resume_without_it(tmp_path):
    assert GeneralTrainConfig().home_input  # new runs read it
    assert not GeneralTrainConfig.from_dict({"sizes": [16]}).home_input  # stored before it
    first = Trainer(GeneralTrainConfig(total_updates=6, home_input=False, **RUN), tmp_path)
    assert not first.online.home_input
    first.run(progress=False)
    state = load_checkpoint(tmp_path / "checkpoint.pt")
    del state["config"]["home_input"], state["network_kwargs"]["home_input"]  # an old run
    atomic_save(state, tmp_path / "checkpoint.pt")
    resumed = Trainer(GeneralTrainConfig(total_updates=9, **RUN), tmp_path)
    assert resumed.online.home_input  # the default, until the checkpoint says otherwise
    assert resumed.resume() and resumed.updates == 6
    assert not resumed.config.home_input and not resumed.online.home_input
    resumed.run(progress=False)
    assert resumed.updates == 9
    assert load_checkpoint(tmp_path / "checkpoint.pt")["config"]["home_input"] is False
    # a run with the input cannot drop it on resume
    with_home = tmp_path / "home"
    Trainer(GeneralTrainConfig(total_updates=3, **RUN), with_home).run(progress=False)
    dropped = Trainer(GeneralTrainConfig(total_updates=6, home_input=False, **RUN), with_home)
    with pytest.raises(CheckpointError, match="home_input True \\(stored\\) vs False"):
        dropped.resume()
