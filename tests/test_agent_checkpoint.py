"""Checkpoints: round trip, exact resume, load_agent, and clear errors for bad files."""

import numpy as np
import pytest
import torch

from cpp_mujoco.agent import CheckpointError, GreedyAgent, MapSizeError, load_agent
from cpp_mujoco.agent.checkpoint import atomic_save, load_checkpoint
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.agent.training_state import TrainingState
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.maps import GridMap, load_map

TINY = dict(
    map="C",
    num_envs=8,
    buffer_size=2_000,
    learning_starts=200,
    eval_every=10**9,
    checkpoint_every=10**9,
    final_eval=False,
    threads=1,
)


def _weights(net):
    return torch.cat([p.detach().reshape(-1) for p in net.parameters()])


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    trainer = Trainer(TrainConfig(total_updates=6, **TINY), out)
    trainer.run(progress=False)
    return out, trainer


def test_files_written_atomically(run_dir):
    out, _ = run_dir
    assert {p.name for p in out.iterdir()} >= {"checkpoint.pt", "agent.pt"}
    assert not list(out.glob("*.tmp"))


def test_agent_round_trip_and_load_agent(run_dir):
    out, trainer = run_dir
    agent = load_agent(out / "agent.pt")
    assert isinstance(agent, GreedyAgent)
    assert torch.equal(_weights(agent.network), _weights(trainer.online))
    mdp = GridMDP(load_map("C"), 4)
    mdp.reset(np.random.default_rng(0))
    obs = mdp.observation()
    batch = agent.act(obs)
    assert batch.shape == (4,) and batch.dtype.kind == "i"
    one = agent.act({k: v[1] for k, v in obs.items()})
    assert isinstance(one, int) and one == batch[1]
    assert agent.metadata["map"] == "C"
    # the training checkpoint loads as an agent too
    assert torch.equal(
        _weights(load_agent(out / "checkpoint.pt").network), _weights(trainer.online)
    )
    # only fp32 weights + metadata in the agent file
    obj = load_checkpoint(out / "agent.pt")
    assert all(v.dtype == torch.float32 for v in obj["network"].values())
    assert "optimizer" not in obj and "replay" not in obj


# the keys of a training checkpoint as every run has written them: a checkpoint of an earlier run
# must resume, so the state's dataclass reads and writes exactly this layout
CHECKPOINT_KEYS = {
    "kind", "format_version", "network", "network_kwargs", "budget_scale", "map", "map_digest",
    "config", "metrics", "rules", "target", "optimizer", "replay", "env", "obs", "ep_return",
    "rng", "torch_gen", "torch_rng", "counters", "recent", "history", "best",
}  # fmt: skip


def test_the_training_state_is_the_checkpoint_layout_both_ways(run_dir):
    out, trainer = run_dir
    stored = load_checkpoint(out / "checkpoint.pt")
    assert set(stored) == CHECKPOINT_KEYS
    assert set(stored["counters"]) == {
        "updates", "episodes", "env_steps", "wall_s", "update_credit"
    }  # fmt: skip
    state = TrainingState.from_checkpoint(stored)
    assert state.progress.updates == trainer.updates == 6
    again = state.to_checkpoint()
    assert set(again) == CHECKPOINT_KEYS and again["counters"] == stored["counters"]
    assert all(torch.equal(again["network"][k], v) for k, v in stored["network"].items())
    # an agent file is not a run's state; nor is a checkpoint that lost part of it
    with pytest.raises(CheckpointError, match="agent file cannot be resumed"):
        TrainingState.from_checkpoint(load_checkpoint(out / "agent.pt"))
    with pytest.raises(CheckpointError, match="lacks replay"):
        TrainingState.from_checkpoint({k: v for k, v in stored.items() if k != "replay"})
    with pytest.raises(CheckpointError, match="counters"):
        TrainingState.from_checkpoint({**stored, "counters": {"updates": 1, "laps": 2}})


def test_resume_continues_exactly(tmp_path):
    config = TrainConfig(total_updates=8, **{**TINY, "checkpoint_every": 4})
    straight = Trainer(config, tmp_path / "a")
    straight.run(progress=False)
    # the same run, interrupted after its checkpoint at update 4 (the learning-rate schedule
    # depends on total_updates, so the interrupted run must be the same configuration)
    first = Trainer(config, tmp_path / "b")
    update = first.update

    def interrupted_update():
        if first.updates == 4:
            raise KeyboardInterrupt
        update()

    first.update = interrupted_update
    with pytest.raises(KeyboardInterrupt):
        first.run(progress=False)
    resumed = Trainer(config, tmp_path / "b")
    assert resumed.resume()
    assert resumed.updates == 4
    resumed.run(progress=False)
    assert resumed.updates == straight.updates and resumed.env_steps == straight.env_steps
    assert torch.allclose(_weights(resumed.online), _weights(straight.online), atol=1e-6)
    assert torch.allclose(_weights(resumed.target), _weights(straight.target), atol=1e-6)


def test_other_map_size_is_a_clear_error(run_dir, tmp_path):
    out, _ = run_dir
    with pytest.raises(CheckpointError, match="16x16 maps"):
        load_checkpoint(out / "agent.pt", map_shape=(8, 8))
    small = GridMap(
        landing=np.eye(8, dtype=bool),
        target=np.ones((8, 8), bool),
        nfz=np.zeros((8, 8), bool),
        name="small",
    )
    mdp = GridMDP(small, 2)
    mdp.reset(np.random.default_rng(0))
    with pytest.raises(MapSizeError, match="16x16"):
        load_agent(out / "agent.pt").act(mdp.observation())


def test_resume_with_other_map_size_fails_clearly(run_dir, tmp_path, monkeypatch):
    out, _ = run_dir
    import cpp_mujoco.agent.map_training as train_mod

    small = GridMap(
        landing=np.eye(8, dtype=bool),
        target=np.ones((8, 8), bool),
        nfz=np.zeros((8, 8), bool),
        name="small",
    )
    monkeypatch.setattr(train_mod, "load_map", lambda _: small)
    trainer = Trainer(TrainConfig(total_updates=6, **TINY), out)
    with pytest.raises(CheckpointError, match="8x8"):
        trainer.resume()


def test_truncated_garbage_and_foreign_files(run_dir, tmp_path):
    out, _ = run_dir
    data = (out / "agent.pt").read_bytes()
    truncated = tmp_path / "truncated.pt"
    truncated.write_bytes(data[: len(data) // 2])
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(np.random.default_rng(0).bytes(5000))
    foreign = tmp_path / "foreign.pt"
    atomic_save({"weights": torch.zeros(3)}, foreign)
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    for path, match in [
        (truncated, "truncated or corrupt"),
        (garbage, "not a torch checkpoint"),
        (foreign, "not a cpp_mujoco checkpoint"),
        (text, "not a torch checkpoint"),
        (tmp_path / "missing.pt", "no such agent file"),
    ]:
        with pytest.raises(CheckpointError, match=match):
            load_agent(path)


def test_unknown_bundled_name():
    with pytest.raises(
        CheckpointError, match="unknown agent 'Z'; bundled: A, A-wind, B, B-wind, C, C-wind"
    ):
        load_agent("Z")
