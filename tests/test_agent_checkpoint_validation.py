"""A checkpoint is never trusted blindly: NaN weights, a bad budget scale or map size, a folder or
a foreign pickle are each a one-line CheckpointError naming the file. Agents name their origin."""

import argparse
import shutil

import pytest
import torch

from cpp_mujoco.agent import BUNDLED_DIR, CheckpointError, load_agent
from cpp_mujoco.agent.checkpoint import TRAIN_KIND, agent_payload, atomic_save, load_checkpoint
from cpp_mujoco.agent.network import QNetwork


def _payload() -> dict:
    torch.manual_seed(0)
    net = QNetwork(4, 4)
    return agent_payload(net, budget_scale=1.0, map_name="tiny", config={})


def _save(tmp_path, obj, name="agent.pt"):
    return atomic_save(obj, tmp_path / name)


def test_a_sound_checkpoint_loads(tmp_path):
    obj = load_checkpoint(_save(tmp_path, _payload()), map_shape=(4, 4))
    assert obj["budget_scale"] == 1.0


@pytest.mark.parametrize(
    "change, match",
    [
        (lambda o: o["network"][next(iter(o["network"]))].view(-1)[3:5].fill_(float("nan")),
         "has 2 NaN/inf value"),
        (lambda o: o["network"][next(iter(o["network"]))].view(-1)[0].fill_(float("inf")),
         "has 1 NaN/inf value"),
        (lambda o: o.update(budget_scale=0.0), "budget_scale 0.0 is not a positive number"),
        (lambda o: o.update(budget_scale=-75.0), "budget_scale -75.0 is not a positive"),
        (lambda o: o.update(budget_scale=float("nan")), "budget_scale nan is not"),
        (lambda o: o.update(budget_scale="75"), "budget_scale '75' is not"),
        (lambda o: o.update(network_kwargs={"height": 0, "width": 4}), "not a map size"),
        (lambda o: o.update(network_kwargs={"height": 4.0, "width": 4}), "not a map size"),
        (lambda o: o.update(network_kwargs={"height": 4, "width": 4, "x": 1}), "not a map size"),
        (lambda o: o.update(network={}), "network holds no weights"),
    ],
)  # fmt: skip
def test_bad_agent_contents_are_refused(tmp_path, change, match):
    obj = _payload()
    change(obj)
    path = _save(tmp_path, obj)
    with pytest.raises(CheckpointError, match=match) as exc:
        load_checkpoint(path)
    assert str(path) in str(exc.value) and "\n" not in str(exc.value)
    with pytest.raises(CheckpointError, match=match):
        load_agent(path)


def test_training_checkpoint_with_nan_target_is_refused(tmp_path):
    obj = {**_payload(), "kind": TRAIN_KIND, "config": {}}
    obj["target"] = {k: v.clone() for k, v in obj["network"].items()}
    name = next(iter(obj["target"]))
    obj["target"][name].view(-1)[0] = float("nan")
    with pytest.raises(CheckpointError, match=f"target network weight '{name}' has 1 NaN"):
        load_checkpoint(_save(tmp_path, obj, "checkpoint.pt"))


def test_a_folder_is_named_as_such(tmp_path):
    with pytest.raises(CheckpointError, match=f"{tmp_path} is a folder, not a checkpoint file"):
        load_checkpoint(tmp_path)
    with pytest.raises(CheckpointError, match="is a folder"):
        load_agent(tmp_path)


def test_foreign_pickle_never_suggests_disabling_weights_only(tmp_path):
    path = tmp_path / "foreign.pt"
    torch.save({"kind": "cpp_mujoco.agent", "args": argparse.Namespace(x=1)}, path)
    with pytest.raises(CheckpointError) as exc:
        load_checkpoint(path)
    message = str(exc.value)
    assert "weights_only" not in message and "\n" not in message
    assert str(path) in message and "not a cpp_mujoco checkpoint" in message


def test_agents_are_named_by_origin(tmp_path):
    bundled = load_agent("A")
    assert bundled.name == "ddqn-A"
    assert bundled.metadata["bundled"] is True
    assert bundled.metadata["source"] == str(BUNDLED_DIR / "A.pt")
    copy = tmp_path / "A.pt"
    shutil.copyfile(BUNDLED_DIR / "A.pt", copy)
    user = load_agent(copy)
    assert user.name == "ddqn-A (file)" and user.name != bundled.name
    assert user.metadata["bundled"] is False and user.metadata["source"] == str(copy.resolve())
    assert user.metadata["digest"] == bundled.metadata["digest"]  # same bytes, same digest
