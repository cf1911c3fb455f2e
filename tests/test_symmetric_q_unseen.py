"""Symmetric Q on unseen maps only: the mean of the 8 images' Q-values everywhere but on the maps
an agent learned in their own orientation, where its own reading; those maps found by digest."""

import numpy as np
import pytest
import torch

from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.general_network import GeneralQNetwork
from cpp_mujoco.agent.policy import GreedyAgent
from cpp_mujoco.agent.rules import SymmetricQ, SymmetricQUnseen, check_rule_names
from cpp_mujoco.agent.rules.base import map_groups
from cpp_mujoco.agent.rules.symmetric_q import own_orientation_maps, own_orientation_rows
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.map_sets.sets import load_map_set
from cpp_mujoco.maps import load_map
from cpp_mujoco.maps.format import layers_digest
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.protocol.policy import policy_identity


def _observations(grid_map, n: int = 6, seed: int = 1) -> dict[str, np.ndarray]:
    mdp = GridMDP(grid_map, n, GridConfig())
    rng = np.random.default_rng(seed)
    mdp.reset(rng, budget=30)
    for _ in range(5):
        mdp.step(rng.integers(4, size=n))
    return mdp.observation()


def _mixed(*parts: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """One batch of several maps' observations, each row carrying its own map."""
    out = {}
    for key in parts[0]:
        rows = [np.broadcast_to(p[key], (len(p["coverage"]), *np.shape(p[key])[-3:]))
                if key == "map" else np.asarray(p[key]) for p in parts]  # fmt: skip
        out[key] = np.concatenate(rows)
    return out


def test_an_observation_names_its_map_by_the_map_s_digest():
    for grid_map in (load_map("A"), load_map("C~rot90"), load_map_set("city32-v1", 1)[0]):
        ((part, rows),) = map_groups(_observations(grid_map, 2))
        assert layers_digest(part["map"], part.get("obstacle")) == grid_map.digest
        assert rows.tolist() == [0, 1]
    assert load_map_set("city32-v1", 1)[0].has_obstacles
    c, turned = load_map("C"), load_map("C~rot90")
    batch = _mixed(_observations(c, 3), _observations(turned, 2))
    own = own_orientation_rows(batch, frozenset({c.digest}))
    np.testing.assert_array_equal(own, [True, True, True, False, False])
    assert not own_orientation_rows(batch, frozenset()).any()


def test_rows_on_a_map_learned_in_its_orientation_take_the_network_s_own_reading():
    torch.manual_seed(0)
    network = GeneralQNetwork(home_input=True, target_input=True)
    c, turned = load_map("C"), load_map("C~rot90")
    batch = _mixed(_observations(c, 6), _observations(turned, 6, seed=2))
    plain = GreedyAgent(network, 75.0).act(batch)
    mean = GreedyAgent(network, 75.0, rules=[SymmetricQ()]).act(batch)
    unseen = GreedyAgent(network, 75.0, rules=[SymmetricQUnseen({c.digest})]).act(batch)
    assert (plain != mean).any()  # a random network: the mean decides otherwise somewhere
    np.testing.assert_array_equal(unseen[:6], plain[:6])
    np.testing.assert_array_equal(unseen[6:], mean[6:])
    every = GreedyAgent(network, 75.0, rules=[SymmetricQUnseen()]).act(batch)
    np.testing.assert_array_equal(every, mean)  # no map of its own: symmetric Q itself


def test_the_agent_files_name_the_maps_they_learned_in_their_orientation():
    general = load_agent("general")
    named = {load_map(n).digest for n in "ABC"}
    assert own_orientation_maps(general.metadata) == named
    config = {**general.metadata["config"], "named_symmetries": True}
    assert own_orientation_maps({**general.metadata, "config": config}) == frozenset()
    assert own_orientation_maps(load_agent("B").metadata) == {load_map("B").digest}
    rule = general.with_rules(["return-mask", "symmetric-q-unseen"]).rules[-1]
    assert isinstance(rule, SymmetricQUnseen) and rule.own_orientation == named
    identity = policy_identity(general.with_rules(["return-mask", "symmetric-q-unseen"]))
    assert identity["own_orientation"] == sorted(named) and "symmetric_q" not in identity
    assert "d4-mean-unseen-v1" in identity["symmetric_q_unseen"]
    with pytest.raises(ValueError, match="exclude each other"):
        check_rule_names(["symmetric-q", "symmetric-q-unseen"])


def test_the_general_agent_flies_its_named_maps_as_before_and_others_with_the_mean():
    general = load_agent("general")
    own = general.rule_names
    unseen = general.with_rules([*own, "symmetric-q-unseen"])
    mean = general.with_rules([*own, "symmetric-q"])
    runs = {}
    for grid_map in (load_map("B"), load_map("B~mirror")):
        runs[grid_map.label] = [
            evaluate(agent, grid_map, budgets=[30, 60]) for agent in (general, unseen, mean)
        ]
    (a, b, _), (_, d, e) = runs["B"], runs["B~mirror"]
    np.testing.assert_array_equal(a.coverage, b.coverage)  # B: its own reading
    np.testing.assert_array_equal(a.steps, b.steps)
    np.testing.assert_array_equal(d.coverage, e.coverage)  # B mirrored: the mean's
    np.testing.assert_array_equal(d.steps, e.steps)
    assert not np.array_equal(runs["B"][2].coverage, a.coverage)  # the mean reads B otherwise
