"""The general agent: one network for any map size, training on a pool of generated maps,
checkpoints that rebuild it, and clear errors for files that are not one."""

import json

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from cpp_mujoco.agent import CheckpointError, MapSizeError, load_agent
from cpp_mujoco.agent.centred_views import _centre_gather, centre_on_uav, centred_views
from cpp_mujoco.agent.checkpoint import atomic_save, load_checkpoint
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_eval import validate
from cpp_mujoco.agent.general_network import GeneralQNetwork
from cpp_mujoco.agent.general_training import check_general_resumable
from cpp_mujoco.agent.map_pool import MapPool
from cpp_mujoco.agent.map_training import check_resumable
from cpp_mujoco.agent.multi_map_env import MultiMapVectorEnv
from cpp_mujoco.agent.multi_map_replay import MultiMapReplay, record_pool_demonstrations
from cpp_mujoco.agent.network import observation_to_tensors
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.map_sets.size_classes import size_config
from cpp_mujoco.maps import load_map
from cpp_mujoco.planners import make_planner

SMALL_NET = dict(local_size=9, global_size=11, conv_filters=8, hidden=64, num_hidden=2)


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """Small nets on a shared 2-core machine: one torch thread."""


def _observation(size: int, seed: int, n: int = 6) -> dict:
    mdp = GridMDP(generate_from_seed(seed, size), n, size_config(size))
    mdp.reset(np.random.default_rng(seed))
    return mdp.observation()


# ------------------------------------------------------------------------------------ network
def test_one_network_for_16_and_32_and_padding_changes_nothing():
    torch.manual_seed(0)
    net = GeneralQNetwork(max_side=32)
    for size in (16, 32):
        grid, scalars = observation_to_tensors(_observation(size, 3), 1.0)
        q = net(grid, scalars)
        assert q.shape == (6, 5) and torch.isfinite(q).all()
    grid, scalars = observation_to_tensors(_observation(16, 4), 1.0)
    padded = torch.zeros(6, 5, 32, 32)
    padded[:, 2] = 1.0  # no-fly outside the map
    padded[:, :, :16, :16] = grid
    assert torch.equal(net(padded, scalars), net(grid, scalars))
    # the canvas: the UAV in the middle, the CPU paste and the batched gather agree
    canvas = centre_on_uav(grid, 32)
    assert canvas.shape == (6, 5, 63, 63) and (canvas[:, 4, 31, 31] == 1).all()
    flat = grid[:, 4].reshape(6, -1).argmax(1)
    assert torch.equal(canvas, _centre_gather(grid, 32, flat // 16, flat % 16))
    assert (canvas[:, 2, 0, 0] == 1).all()  # far corner: outside any 16×16 map


def _canvas_views(grid, side, local_size, global_size):
    """The views by definition: crop and pool the centred canvas."""
    canvas = centre_on_uav(grid, side)
    mid, half = canvas.shape[-1] // 2, local_size // 2
    local = canvas[..., mid - half : mid + half + 1, mid - half : mid + half + 1]
    return local, F.adaptive_avg_pool2d(canvas, global_size)


@pytest.mark.parametrize("size", [16, 32])
@pytest.mark.parametrize("side,local_size,global_size", [(32, 17, 21), (40, 9, 20), (32, 5, 13)])
def test_views_without_the_canvas_equal_the_canvas_views(size, side, local_size, global_size):
    grid, _ = observation_to_tensors(_observation(size, 7, n=12), 1.0)
    grid[:, 3] = torch.rand(12, size, size, generator=torch.Generator().manual_seed(1)) < 0.5
    got = centred_views(grid, side, local_size, global_size)
    want = _canvas_views(grid, side, local_size, global_size)
    assert torch.equal(got[0], want[0]) and torch.equal(got[1], want[1])  # 0/1: exact sums
    wide = torch.rand(12, 5, size - 3, size)  # not square, not 0/1
    wide[:, 4] = 0.0
    k = torch.arange(12)
    wide[k, 4, k * 5 % (size - 3), k * 7 % size] = 1.0
    local, glob = centred_views(wide, side, local_size, global_size)
    want_local, want_glob = _canvas_views(wide, side, local_size, global_size)
    assert torch.equal(local, want_local)
    assert torch.allclose(glob, want_glob, atol=1e-6)


# ------------------------------------------------------------------------ pool, env, replay
@pytest.fixture(scope="module")
def pool():
    return MapPool.generate((16, 32), 3, 0)


def test_pool_pads_maps_and_keeps_seed_ranges_apart(pool):
    assert len(pool) == 6 and pool.side == 32 and pool.sizes == [16, 32]
    first = pool.maps[0]
    assert np.array_equal(pool.layers[0, :, :16, :16], first.layers)
    assert (pool.layers[0, 2, 16:] == 1).all() and (pool.layers[0, :2, 16:] == 0).all()
    assert pool.configs[0].max_budget == 75 and pool.configs[3].max_budget == 150
    with pytest.raises(ValueError, match="held-out"):
        GeneralTrainConfig(map_seed=999_999, maps_per_size=2)
    with pytest.raises(ValueError, match="validation map seeds"):
        GeneralTrainConfig(val_seed=5)


def test_replay_returns_each_transitions_own_map(pool):
    env = MultiMapVectorEnv(pool, num_envs=5)
    replay = MultiMapReplay(400, 5, pool, n_step=3, gamma=0.9)
    rng = np.random.default_rng(0)
    obs, _ = env.reset(seed=1)
    seen = []  # the observations stored, row by row
    for _ in range(79):
        actions = rng.integers(5, size=5)
        nxt, reward, terminated, _, _ = env.step(actions)
        replay.add(obs, actions, reward, terminated)
        seen.append(obs)
        obs = nxt
    assert len({int(m) for o in seen for m in o["map_index"]}) >= 4  # maps change at resets
    t = rng.integers(replay._valid_rows(), size=200)
    e = rng.integers(5, size=200)
    s = replay.transitions(t, e)
    grid = s["obs"][0]
    for k, (row, env_id) in enumerate(zip(t, e, strict=True)):
        o = seen[row]
        m = int(o["map_index"][env_id])
        h, w = pool.maps[m].shape
        assert np.array_equal(grid[k, :3, :h, :w], pool.maps[m].layers)  # cell by cell
        assert (grid[k, 2, h:] == 1).all() and (grid[k, 2, :, w:] == 1).all()
        assert np.array_equal(grid[k, 3], o["coverage"][env_id])
        assert np.array_equal(grid[k, 4], o["position"][env_id])
        assert s["obs"][1][k, 0] == o["budget"][env_id, 0]
        if s["discount"][k] > 0:  # the bootstrap state: same episode, so the same map
            assert np.array_equal(s["next_obs"][0][k, :3], grid[k, :3])


def test_demonstrations_are_kept_per_map(pool):
    demos = record_pool_demonstrations(pool, [0, 3], make_planner("safe-greedy"), 3, 0.95, 25)
    assert set(np.unique(demos.map_index)) == {0, 3} and demos.landing_ratio == 1.0
    s = demos.sample(64, np.random.default_rng(0))
    for k in range(64):
        grid, nxt = s["obs"][0][k], s["next_obs"][0][k]
        maps = [m for m in (0, 3) if np.array_equal(grid[:3], pool.layers[m])]
        assert len(maps) == 1 and np.array_equal(nxt[:3], grid[:3])
        cell = np.unravel_index(grid[4].argmax(), grid[4].shape)
        assert grid[2][cell] == 0  # the UAV is on a flyable cell of that map


def test_env_state_round_trip(pool):
    env = MultiMapVectorEnv(pool, 4)
    env.reset(seed=3)
    for _ in range(30):
        env.step(np.arange(4) % 5)
    copy = MultiMapVectorEnv(pool, 4)
    copy.load_state_dict(env.state_dict())
    for _ in range(40):
        a, b = env.step([1, 2, 3, 4]), copy.step([1, 2, 3, 4])
        for key in a[0]:
            assert np.array_equal(a[0][key], b[0][key]), key
    with pytest.raises(ValueError, match="map_index"):
        MultiMapVectorEnv(pool, 3).load_state_dict(env.state_dict())


# ------------------------------------------------------------------------------- training
TINY = dict(
    sizes=(16,), maps_per_size=4, val_maps_per_size=1, demo_maps_per_size=4,
    demo_budget_step=10, num_envs=16, learning_starts=500, batch_size=64, learning_rate=1e-3,
    lr_warmup_updates=20, eval_every=10**9, checkpoint_every=10**9, final_eval=False,
    threads=1, guide_updates=300, buffer_size=20_000, checkpoint_minutes=0, eval_budget_step=25,
    **SMALL_NET,
)  # fmt: skip


UPDATES = 150  # the trained fixture's run, and the configs compared with it


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    out = tmp_path_factory.mktemp("general")
    trainer = Trainer(GeneralTrainConfig(total_updates=UPDATES, **TINY), out)
    trainer.run(progress=False)
    return out, trainer


def test_smoke_training_beats_random_on_its_maps(trained):
    _, trainer = trained
    agent = validate(trainer.agent(), trainer.maps.pool, budget_step=10)
    rand = validate(make_planner("random"), trainer.maps.pool, budget_step=10)
    # measured: 0.46 vs 0.056 (seeds 1, 2: 0.45, 0.38; an untrained network: 0.04)
    assert agent.coverage_ratio > rand.coverage_ratio + 0.15


def test_checkpoint_rebuilds_the_general_agent(trained):
    out, trainer = trained
    agent = load_agent(out / "agent.pt")
    assert agent.map_shape is None and agent.metadata["architecture"] == "general"
    assert isinstance(agent.network, GeneralQNetwork)
    assert agent.network.kwargs == trainer.online.kwargs
    for size in (16, 32):
        obs = _observation(size, 5)
        actions = agent.act(obs)
        assert actions.shape == (6,)
        assert agent.act({k: v[2] for k, v in obs.items()}) == actions[2]
        assert np.array_equal(actions, trainer.agent().act(obs))
    # the paper's networks still fly only their own size
    with pytest.raises(MapSizeError, match="16x16"):
        load_agent("A").act(_observation(32, 5))


def test_resume_refuses_other_pools_and_architectures(trained, tmp_path):
    out, trainer = trained
    state = load_checkpoint(out / "checkpoint.pt")
    other = MapPool.generate((16,), 4, 100)
    with pytest.raises(CheckpointError, match="another map pool"):
        check_general_resumable(out / "checkpoint.pt", state, trainer.config, other)
    changed = GeneralTrainConfig(total_updates=UPDATES, **{**TINY, "gamma": 0.9})
    with pytest.raises(CheckpointError, match="gamma"):
        check_general_resumable(out / "checkpoint.pt", state, changed, trainer.maps.pool)
    with pytest.raises(CheckpointError, match="train-general"):
        check_resumable(out / "checkpoint.pt", state, TrainConfig(), load_map("A"))
    paper = load_checkpoint(load_agent("A").metadata["source"])
    with pytest.raises(CheckpointError, match="per-map run"):
        check_general_resumable(out / "checkpoint.pt", paper, trainer.config, trainer.maps.pool)


def test_resume_continues_and_final_eval_has_the_reference(tmp_path):
    short = {**TINY, "learning_starts": 64, "final_eval": True, "final_budget_step": 25}
    first = Trainer(GeneralTrainConfig(total_updates=6, **short), tmp_path)
    first.run(progress=False)
    state = load_checkpoint(tmp_path / "checkpoint.pt")
    for group in state["optimizer"]["param_groups"]:
        group["fused"] = None  # as checkpoints from before the fused Adam step recorded it
    atomic_save(state, tmp_path / "checkpoint.pt")
    resumed = Trainer(GeneralTrainConfig(total_updates=9, **short), tmp_path)
    assert resumed.resume() and resumed.updates == 6 and resumed.env_steps == first.env_steps
    assert all(group["fused"] for group in resumed.optimizer.param_groups)
    assert [(h["updates"], h["eval_coverage"]) for h in resumed.history] == [
        (h["updates"], h["eval_coverage"]) for h in first.history
    ]
    resumed.run(progress=False)
    assert resumed.updates == 9
    final = json.loads((tmp_path / "final_eval.json").read_text())
    assert final["map_set"]["name"] == "validation" and final["map_set"]["maps"] == 1
    assert final["conditions"]["training"]["updates"] == 9
    agent, reference = final["policies"]  # the agent, the reference planner beside it
    assert agent["policy"] == "ddqn-general" and agent["maps"] == 1
    assert reference["policy"] == "safe-greedy" and reference["mean_landing_ratio"] == 1.0
    assert {r["policy"] for r in final["rows"]} == {"ddqn-general", "safe-greedy"}


def test_bad_general_checkpoints_are_clear_errors(trained, tmp_path):
    out, _ = trained
    data = (out / "agent.pt").read_bytes()
    truncated = tmp_path / "truncated.pt"
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(CheckpointError, match="truncated or corrupt"):
        load_agent(truncated)
    good = load_checkpoint(out / "agent.pt")
    for change, match in [
        ({"network_kwargs": {**good["network_kwargs"], "local_size": "17"}}, "local_size"),
        ({"network_kwargs": {**good["network_kwargs"], "height": 16}}, "unknown network_kwargs"),
        ({"architecture": "transformer"}, "unknown network architecture"),
        ({"network_kwargs": {**good["network_kwargs"], "hidden": 32}}, "do not fit"),
    ]:
        path = tmp_path / "bad.pt"
        atomic_save({**good, **change}, path)
        with pytest.raises(CheckpointError, match=match):
            load_agent(path)


def test_cli_builds_the_general_config():
    from cpp_mujoco.cli.main import build_parser

    args = build_parser().parse_args(
        ["train-general", "--out", "x", "--sizes", "16", "32", "--maps-per-size", "8",
         "--total-updates", "100", "--set", "local_size=9"]
    )  # fmt: skip
    from cpp_mujoco.cli.train_general import config_from_args, resume_command

    config = config_from_args(args)
    assert config.sizes == (16, 32) and config.maps_per_size == 8 and config.local_size == 9
    resume = resume_command(args)
    assert (
        "--sizes 16 32" in resume and "--set local_size=9" in resume and "train-general" in resume
    )
    args.settings = ["local_size=8"]
    with pytest.raises(ValueError, match="invalid setting: local_size"):
        config_from_args(args)
    args.settings = ["map=B"]  # a per-map setting the general run does not take
    with pytest.raises(ValueError, match="setting 'map' is not one of this command's"):
        config_from_args(args)


def test_a_general_agent_flies_a_held_out_set(trained, tmp_path, capsys):
    from cpp_mujoco.cli.main import main

    out, _ = trained
    argv = ["evaluate", "--map-set", "heldout32-v1", "--first", "1", "--budget-step", "50",
            "--agent", str(out / "agent.pt"), "--out", str(tmp_path), "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    assert "map set heldout32-v1: 1 of" in capsys.readouterr().out
    result = json.loads((tmp_path / "grid_heldout32-v1_first1.json").read_text())
    assert result["policies"][0]["episodes"] > 0


def test_runs_from_before_the_architecture_option_still_resume(trained):
    # their configs have no "architecture": they are global-local runs, and --architecture fcn
    # is refused with the reason
    out, trainer = trained
    state = load_checkpoint(out / "checkpoint.pt")
    assert state["architecture"] == "general" and state["config"]["architecture"] == "global-local"
    del state["config"]["architecture"]
    check_general_resumable(out / "checkpoint.pt", state, trainer.config, trainer.maps.pool)
    fcn = GeneralTrainConfig(total_updates=UPDATES, **{**TINY, "architecture": "fcn"})
    with pytest.raises(CheckpointError, match="--architecture global-local"):
        check_general_resumable(out / "checkpoint.pt", state, fcn, trainer.maps.pool)
