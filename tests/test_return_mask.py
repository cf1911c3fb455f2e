"""The return mask: the safe greedy planner's return rule as an action set, cell by cell; the
same from an observation as from the map's graph and the replay; a masked policy lands every
calm episode (an untrained network included) and training never takes an unsafe action."""

import numpy as np
import pytest
import torch

from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.checkpoint import CheckpointError, atomic_save, load_checkpoint
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.ddqn import ddqn_target, mask_unsafe
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_network import GeneralQNetwork
from cpp_mujoco.agent.general_training import general_parts, initial_general_weights
from cpp_mujoco.agent.home_input import safe_actions
from cpp_mujoco.agent.map_pool import MapPool, padded_cell
from cpp_mujoco.agent.policy import GreedyAgent
from cpp_mujoco.agent.rules import ReturnMask
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.grid.actions import LAND, MOVES
from cpp_mujoco.grid.graph import build_graph
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.grid.return_rule import RETURN_RULE
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.maps import load_map
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.episode import run_batch
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets
from tests.test_home_input import _bfs_moves_home

SMALL_NET = dict(local_size=9, global_size=11, conv_filters=8, hidden=64, num_hidden=2)


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """Small nets on a shared 2-core machine: one torch thread."""


def _reference_home(grid_map) -> np.ndarray:
    """Actions to be landed from each cell (breadth-first moves to a landing cell + the land);
    -1: no way."""
    moves = _bfs_moves_home(grid_map)
    return np.where(moves >= 0, moves + 1, -1)


@pytest.mark.parametrize("name", ["A", "C"])
def test_the_rule_cell_by_cell(name):
    """At budget b in cell p an action is safe iff it lands, or it is a move the safety
    controller accepts and b − 1 still pays the way home from where it leads (a rejected action
    only hovers: never safe). At b = home(p) exactly that leaves the land on a landing cell and
    the moves one step nearer home; every kept state has a safe action."""
    grid_map = load_map(name)
    graph = build_graph(grid_map)
    home = _reference_home(grid_map)
    h, w = grid_map.shape
    checked = 0
    for r, c in zip(*np.nonzero(home > 0), strict=True):
        p = r * w + c
        assert graph.home[p] == home[r, c]
        for b in range(home[r, c], home[r, c] + 3):
            safe = graph.safe_actions(np.array([p]), np.array([b]))[0]
            for a in range(LAND + 1):
                if a == LAND:
                    expected = bool(grid_map.landing[r, c])
                else:
                    rr, cc = r + MOVES[a, 0], c + MOVES[a, 1]
                    inside = 0 <= rr < h and 0 <= cc < w and not grid_map.nfz[rr, cc]
                    expected = inside and b - 1 >= home[rr, cc]
                assert safe[a] == expected, (name, r, c, b, a)
                checked += 1
            assert safe.any()
            if b == home[r, c]:
                nearer = [
                    a
                    for a in range(LAND)
                    if 0 <= r + MOVES[a, 0] < h
                    and 0 <= c + MOVES[a, 1] < w
                    and home[r + MOVES[a, 0], c + MOVES[a, 1]] == b - 1
                ]
                if grid_map.landing[r, c]:
                    nearer.append(LAND)
                assert sorted(np.flatnonzero(safe)) == sorted(nearer)
    assert checked > 1000


def test_the_safe_greedy_planner_keeps_the_rule():
    """The rule is the planner's invariant as an action set: on map B, every start × every
    5th budget, it never takes an action outside it."""
    grid_map = load_map("B")
    graph = build_graph(grid_map)
    config = size_config(16)
    budgets = np.asarray(protocol_budgets(config, 5))
    starts = np.flatnonzero(grid_map.landing)
    mdp = GridMDP(grid_map, starts.size * budgets.size, config)
    start_rc = np.stack(np.divmod(np.repeat(starts, budgets.size), grid_map.shape[1]), axis=1)
    mdp.reset(np.random.default_rng(0), start=start_rc, budget=np.tile(budgets, starts.size))
    taken = []

    def check(obs, actions, outcome, active):
        cells = np.asarray(obs["position"]).reshape(actions.size, -1).argmax(axis=1)
        safe = graph.safe_actions(cells, np.asarray(obs["budget"]).reshape(-1))
        taken.append(safe[np.arange(actions.size), actions][active])

    run_batch(mdp, make_planner("safe-greedy"), on_step=check)
    assert mdp.landed.all()
    assert np.concatenate(taken).all() and sum(t.size for t in taken) > 1000


def _observation(grid_map, cells, budgets):
    h, w = grid_map.shape
    position = np.zeros((len(cells), h, w), dtype=np.int8)
    for i, p in enumerate(cells):
        position[i].reshape(-1)[p] = 1
    return {
        "map": grid_map.layers.astype(np.int8),
        "position": position,
        "budget": np.asarray(budgets, dtype=np.float32).reshape(-1, 1),
        "coverage": np.zeros((len(cells), h, w), dtype=np.int8),
    }


def test_observation_pool_and_graph_give_the_same_rule():
    """One map shared by a batch, one map per row (16×16 maps padded to 32 among 32×32 ones)
    and the pool's stored states all answer as the map's own graph."""
    rng = np.random.default_rng(3)
    pool = MapPool.generate((16, 32), 2, 40)
    rows, expected = [], []
    for m, grid_map in enumerate(pool.maps):
        graph = build_graph(grid_map)
        cells = rng.choice(np.flatnonzero(graph.home < 10**6), size=8)
        budgets = graph.home[cells] + rng.integers(-1, 3, size=8)
        want = graph.safe_actions(cells, budgets)
        expected.append(want)
        obs = _observation(grid_map, cells, budgets)
        assert np.array_equal(safe_actions(obs["map"], obs["position"], obs["budget"]), want)
        padded = padded_cell(cells, grid_map.shape[1], pool.side)
        assert np.array_equal(pool.safe_actions(np.full(8, m), padded, budgets), want)
        position = np.zeros((8, pool.side, pool.side), dtype=np.int8)
        position.reshape(8, -1)[np.arange(8), padded] = 1
        rows.append((np.repeat(pool.layers[m][None], 8, axis=0), position, budgets))
    maps, position, budgets = (np.concatenate(x) for x in zip(*rows, strict=True))
    order = rng.permutation(maps.shape[0])  # maps interleaved row by row
    got = safe_actions(maps[order], position[order], budgets[order])
    assert np.array_equal(got, np.concatenate(expected)[order])


def test_mask_unsafe_and_the_masked_target():
    q = torch.tensor([[1.0, 5.0, 2.0, 0.0, 3.0], [4.0, 1.0, 0.0, 2.0, 9.0]])
    safe = torch.tensor([[True, False, True, False, False], [False] * 5])
    masked = mask_unsafe(q, safe)
    assert masked[0].argmax() == 2 and torch.isinf(masked[0, [1, 3, 4]]).all()
    assert torch.equal(masked[1], q[1])  # no safe action: left as it is

    class Net(torch.nn.Module):
        def forward(self, grid, scalars):
            return grid

    y = ddqn_target(Net(), Net(), q, None, torch.zeros(2), torch.ones(2), safe)
    assert y.tolist() == [2.0, 9.0]
    assert ddqn_target(Net(), Net(), q, None, torch.zeros(2), torch.ones(2)).tolist() == [5, 9]


@pytest.mark.parametrize("size", [16, 32])
def test_a_masked_policy_lands_every_episode_even_untrained(size):
    torch.manual_seed(0)
    net = GeneralQNetwork(max_side=32, home_input=True, **SMALL_NET)
    grid_map, config = generate_from_seed(2_000_017, size), size_config(size)
    budgets = protocol_budgets(config, {16: 10, 32: 20}[size])  # six spanning the size class
    free = evaluate(GreedyAgent(net, 150.0), grid_map, budgets=budgets, config=config)
    masked = evaluate(
        GreedyAgent(net, 150.0, rules=[ReturnMask()]), grid_map, budgets=budgets, config=config
    )
    assert masked.landing_ratio == 1.0
    assert free.landing_ratio < 0.5  # the untrained network alone strands the UAV


TINY = dict(
    sizes=(16, 32), maps_per_size=3, val_maps_per_size=1, demo_maps_per_size=1,
    demo_budget_step=25, num_envs=8, batch_size=16, buffer_size=4000, learning_starts=200,
    eval_every=1000, eval_budget_step=25, final_eval=False, threads=1, guide_updates=100,
    **SMALL_NET,
)  # fmt: skip


@pytest.fixture(scope="module")
def masked_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("masked")
    trainer = Trainer(GeneralTrainConfig(total_updates=40, **TINY), out)
    trainer.run(progress=False)
    return out, trainer


def test_training_takes_only_safe_actions_and_masks_its_targets(masked_run):
    _, trainer = masked_run
    assert trainer.config.return_mask
    replay, n = trainer.replay, trainer.replay.pos
    t, e = np.divmod(np.arange(n * replay.num_envs), replay.num_envs)
    safe = replay._safe(t, e)
    assert np.array_equal(
        safe, trainer.maps.pool.safe_actions(replay.map_index[t, e], replay.position[t, e],
                                        replay.budget[t, e])
    )  # fmt: skip
    assert safe[np.arange(t.size), replay.action[t, e]].all()  # the guide's and the agent's
    batch = trainer.batch()
    assert batch["next_safe"].shape == (16, 5) and batch["next_safe"].any(dim=1).all()


def test_agent_files_carry_the_mask_and_old_ones_fly_without(masked_run, tmp_path):
    out, trainer = masked_run
    agent = load_agent(out / "agent.pt")
    assert agent.return_mask and agent.metadata["return_mask"]
    state = load_checkpoint(out / "agent.pt")
    assert state["rules"][0] == "return-mask"  # the file names its rules
    del state["config"]["return_mask"], state["rules"]  # an agent from before the option
    atomic_save(state, tmp_path / "old.pt")
    assert not load_agent(tmp_path / "old.pt").return_mask
    assert not load_agent("A").return_mask  # the paper's agents


def test_results_name_the_mask_and_its_rule(masked_run):
    out, trainer = masked_run
    agent = load_agent(out / "agent.pt")
    result = evaluate(
        agent, trainer.maps.pool.maps[0], budgets=[25], config=trainer.maps.pool.configs[0]
    )
    policy = result.conditions["policy"]
    assert policy["return_mask"] and policy["return_rule"] == RETURN_RULE
    assert "return_rule" not in evaluate(load_agent("A"), "A", budgets=[25]).conditions["policy"]


def test_init_from_starts_from_a_general_agents_weights(masked_run, tmp_path):
    out, trainer = masked_run
    config = GeneralTrainConfig(total_updates=1, init_from=str(out / "agent.pt"), **TINY)
    weights = initial_general_weights(config)
    started = Trainer(config, tmp_path, general_parts(config, weights))
    for a, b in zip(started.online.parameters(), trainer.online.parameters(), strict=True):
        assert torch.equal(a, b)
    wider = GeneralTrainConfig(init_from=str(out / "agent.pt"), **{**TINY, "hidden": 32})
    with pytest.raises(CheckpointError, match="this run's network"):
        initial_general_weights(wider)
    paper = GeneralTrainConfig(init_from=load_agent("A").metadata["source"], **TINY)
    with pytest.raises(CheckpointError, match="paper"):
        initial_general_weights(paper)


def test_the_mask_is_refused_where_moves_cost_more():
    with pytest.raises(ValueError, match="return_mask"):
        TrainConfig(return_mask=True, wind_max_speed=12.0)
    with pytest.raises(ValueError, match="return_mask"):
        TrainConfig(return_mask=True, backend="mujoco", init_from="A", physics_wind_speed=0.0)
    assert not TrainConfig().return_mask and GeneralTrainConfig().return_mask
    assert not GeneralTrainConfig.from_dict({}).return_mask  # a run from before the option
