"""Policy rules as plug-ins: one registry, one list per agent file, named in every result."""

import numpy as np
import pytest
import torch

from cpp_mujoco.agent import CheckpointError, load_agent
from cpp_mujoco.agent.checkpoint import load_checkpoint
from cpp_mujoco.agent.rules import (
    RULES,
    FinishMask,
    ReturnMask,
    RevisitMask,
    SymmetricQ,
    make_rules,
    rule_names_of,
    rules_identity,
)
from cpp_mujoco.cli import options
from cpp_mujoco.cli.main import main
from cpp_mujoco.grid.mdp import GridMDP
from cpp_mujoco.maps import load_map


def test_the_command_line_names_the_registry_s_rules_in_its_order():
    assert list(options.RULES) == list(RULES)
    assert [cls.name for cls in RULES.values()] == list(RULES)
    one_symmetric = [n for n in RULES if n != "symmetric-q-unseen"]
    assert [r.name for r in make_rules(reversed(one_symmetric))] == one_symmetric  # in order
    with pytest.raises(ValueError, match="exclude each other"):
        make_rules(RULES)
    with pytest.raises(ValueError, match="unknown rule 'nope'; known: return-mask"):
        make_rules(["nope"])


def test_files_from_before_the_list_read_their_booleans_as_the_same_list():
    old = {"config": {"return_mask": True, "revisit_mask": True, "symmetric_q": False}}
    assert rule_names_of(old) == ["return-mask", "revisit-mask"]
    assert rule_names_of({"config": {}}) == []  # the paper's agents
    assert rule_names_of({"rules": ["finish-mask", "return-mask"], **old}) == [
        "return-mask",
        "finish-mask",
    ]  # the list wins
    general = load_checkpoint(load_agent("general").metadata["source"])
    own = ["return-mask", "revisit-mask", "finish-mask"]
    assert load_agent("general").rule_names == rule_names_of(general) == [*own, "progress-mask"]
    # the file without its list: its config's booleans, the rules from before the list
    assert rule_names_of({k: v for k, v in general.items() if k != "rules"}) == own


def test_a_file_with_a_bad_rule_list_is_refused_with_its_name(tmp_path):
    obj = load_checkpoint(load_agent("C").metadata["source"])
    for bad, match in ((["nope"], "unknown rule 'nope'"), ("return-mask", "must be a list")):
        path = tmp_path / "bad.pt"
        torch.save({**obj, "rules": bad}, path)
        with pytest.raises(CheckpointError, match=match):
            load_agent(path)
    torch.save({**obj, "rules": ["return-mask"]}, tmp_path / "masked.pt")
    masked = load_agent(tmp_path / "masked.pt")
    assert masked.rule_names == ["return-mask"] and masked.metadata["rules"] == ["return-mask"]


def test_results_name_the_rules_from_the_one_list():
    general = load_agent("general")
    identity = general.identity()
    assert identity["return_mask"] and identity["revisit_mask"] and identity["finish_mask"]
    assert identity["return_rule"] == ReturnMask.rule
    assert identity["revisit_rule"] == RevisitMask.rule
    assert identity["finish_rule"] == FinishMask.rule
    assert "symmetric_q" not in identity  # recorded only when on
    plain = general.with_rules([])
    assert plain.metadata["rules"] == [] and not plain.metadata["finish_mask"]  # says what it flies
    assert (
        general.metadata["finish_mask"] and plain.metadata["digest"] == general.metadata["digest"]
    )
    assert rules_identity(plain.rules) == {
        "return_mask": False,
        "revisit_mask": False,
        "finish_mask": False,
    }
    assert plain.identity()["network"] == identity["network"]
    assert general.with_rules(["symmetric-q"]).identity()["symmetric_q"] == SymmetricQ.rule


def test_symmetric_q_as_the_last_rule_takes_the_mean_s_argmax_among_the_allowed():
    agent = load_agent("general").with_rules(["return-mask", "symmetric-q"])
    mdp = GridMDP(load_map("B"), 16)
    mdp.reset(np.random.default_rng(3))
    obs = mdp.observation()
    allowed = make_rules(["return-mask"])[0].allowed(obs, np.ones((16, 5), bool), None, None)
    q = torch.from_numpy(agent.q_values(obs))
    from cpp_mujoco.grid.symmetry import symmetric_q_values

    mean = torch.from_numpy(symmetric_q_values(agent.q_values, obs))
    expected = mean.masked_fill(~torch.from_numpy(allowed), float("-inf")).argmax(1).numpy()
    np.testing.assert_array_equal(agent.act(obs), expected)
    assert q.shape == (16, 5)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--rule", "+finish-mask"], "give --agent too"),
        (["--value-beam", "8"], "give --agent too"),
        (["--agent", "C", "--rule", "none", "--rule", "return-mask"], "give it alone"),
        (["--agent", "C", "--rule", "return-mask", "--rule", "no-finish-mask"], "not both"),
    ],
)
def test_bad_rule_options_are_one_line_before_anything_runs(argv, message, tmp_path, capsys):
    assert main(["evaluate", *argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and message in err and not (tmp_path / "out").exists()


def test_rules_for_changes_the_file_s_own():
    own = ["return-mask", "revisit-mask", "finish-mask"]
    assert options.rules_for(own, None) == own
    assert options.rules_for(own, ["no-finish-mask", "+symmetric-q"]) == [
        "return-mask",
        "revisit-mask",
        "symmetric-q",
    ]
    assert options.rules_for(own, ["finish-mask"]) == ["finish-mask"]
    assert options.rules_for(own, ["none"]) == []
