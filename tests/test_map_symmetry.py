"""The grid's symmetries: a turned or mirrored map flown with the turned actions is the same
mission, cell by cell; a symmetric Q-estimate is the same on every image of a state."""

import json

import numpy as np
import pytest
import torch

from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.general_network import GeneralQNetwork
from cpp_mujoco.agent.policy import GreedyAgent
from cpp_mujoco.agent.rules import SymmetricQ
from cpp_mujoco.grid.actions import EAST, LAND, NORTH, SOUTH, WEST
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.grid.symmetry import (
    action_permutation,
    shares_one_map,
    symmetric_q_values,
    turn_observation,
)
from cpp_mujoco.grid.wind import action_kind, wind_velocity
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.map_sets.sets import load_map_set
from cpp_mujoco.maps import GridMap, MapError, load_map
from cpp_mujoco.maps.symmetry import (
    IDENTITY,
    SYMMETRIES,
    Symmetry,
    map_images,
    symmetries_of,
    turn_cells,
    turn_map,
    turn_wind,
)
from cpp_mujoco.protocol.policy import policy_identity


def test_the_group_has_eight_distinct_elements_and_its_action_maps_are_permutations():
    cells = np.arange(12).reshape(3, 4)
    square = np.arange(16).reshape(4, 4)
    assert len({turn_cells(square, s).tobytes() for s in SYMMETRIES}) == 8
    assert len(symmetries_of((4, 4))) == 8 and len(symmetries_of((3, 4))) == 4
    assert all(turn_cells(cells, s).shape == (3, 4) for s in symmetries_of((3, 4)))
    for s in SYMMETRIES:
        perm = action_permutation(s)
        assert sorted(perm.tolist()) == [0, 1, 2, 3, 4] and perm[LAND] == LAND
    # a quarter turn counter-clockwise: what lay north of the UAV lies west of it
    quarter = Symmetry(False, 1)
    assert action_permutation(quarter)[[NORTH, EAST, SOUTH, WEST]].tolist() == [
        WEST, NORTH, EAST, SOUTH,
    ]  # fmt: skip
    assert action_permutation(Symmetry(True, 0))[[EAST, WEST]].tolist() == [WEST, EAST]


@pytest.mark.parametrize("symmetry", SYMMETRIES[1:], ids=lambda s: s.name)
def test_a_turned_map_flown_with_the_turned_actions_is_the_same_mission(symmetry):
    grid_map = generate_from_seed(3, 16)
    image = turn_map(grid_map, symmetry)
    assert image.name == f"{grid_map.name}~{symmetry.name}" and image.digest != grid_map.digest
    n, rng = 64, np.random.default_rng(0)
    starts = np.argwhere(grid_map.landing)[rng.integers(int(grid_map.landing.sum()), size=n)]
    index = np.arange(256).reshape(16, 16)
    turned_index = turn_cells(index, symmetry)  # turned_index[cell of the image] = map's cell
    where = {int(c): divmod(int(i), 16) for i, c in enumerate(turned_index.reshape(-1))}
    budgets = rng.integers(10, 40, size=n)
    mdp, twin = GridMDP(grid_map, n), GridMDP(image, n)
    mdp.reset(rng, start=starts, budget=budgets)
    twin.reset(rng, start=np.array([where[r * 16 + c] for r, c in starts]), budget=budgets)
    perm = action_permutation(symmetry)
    for _ in range(40):
        actions = rng.integers(5, size=n)
        a, b = mdp.step(actions), twin.step(perm[actions])
        for key in ("reward", "terminated", "rejected", "crashed", "newly_seen"):
            np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)
        obs = turn_observation(mdp.observation(), symmetry)
        seen = twin.observation()
        for key in ("map", "coverage", "position", "budget"):
            np.testing.assert_array_equal(obs[key], seen[key], err_msg=key)


@pytest.mark.parametrize("wind_from", [0.0, 90.0, 180.0, 270.0])
@pytest.mark.parametrize("symmetry", SYMMETRIES, ids=lambda s: s.name)
def test_the_wind_turns_with_the_map(symmetry, wind_from):
    """Each action's kind (upwind, downwind, crosswind) is its image's in the turned wind."""
    velocity = wind_velocity(np.array([7.0]), np.array([wind_from]))
    turned = turn_wind(velocity, symmetry)
    candidates = np.array([0.0, 90.0, 180.0, 270.0])
    match = [f for f in candidates if np.allclose(wind_velocity(np.array([7.0]), [f]), turned)]
    assert len(match) == 1
    moves = np.arange(4)
    kinds = action_kind(moves, np.zeros(4, bool), np.zeros(4, bool), np.full(4, wind_from))
    turned_kinds = action_kind(
        action_permutation(symmetry)[moves], np.zeros(4, bool), np.zeros(4, bool),
        np.full(4, match[0]),
    )  # fmt: skip
    np.testing.assert_array_equal(kinds, turned_kinds)


def _observations(grid_map: GridMap, n: int = 6) -> dict[str, np.ndarray]:
    mdp = GridMDP(grid_map, n, GridConfig())
    rng = np.random.default_rng(1)
    mdp.reset(rng, budget=30)
    for _ in range(5):
        mdp.step(rng.integers(4, size=n))
    return mdp.observation()


def test_symmetric_q_values_are_the_same_on_every_image_of_a_state():
    torch.manual_seed(0)
    network = GeneralQNetwork(home_input=True, target_input=True)
    agent = GreedyAgent(network, 75.0, rules=[SymmetricQ()])
    plain = GreedyAgent(network, 75.0)
    obs = _observations(load_map("C"))
    q = symmetric_q_values(agent.q_values, obs)
    assert not np.allclose(q, plain.q_values(obs), atol=1e-4)  # a random network is not symmetric
    for symmetry in SYMMETRIES:
        image_q = symmetric_q_values(agent.q_values, turn_observation(obs, symmetry))
        np.testing.assert_allclose(image_q[:, action_permutation(symmetry)], q, atol=1e-5)
    np.testing.assert_array_equal(agent.act(obs), q.argmax(axis=1))  # the rule acts on the mean
    assert "d4-mean" in policy_identity(agent)["symmetric_q"]
    assert "symmetric_q" not in policy_identity(plain)


def test_a_non_square_map_reads_the_four_images_that_keep_its_shape():
    wide = GridMap(
        landing=np.pad(np.ones((2, 2), bool), ((0, 10), (0, 18))),
        target=np.pad(np.ones((3, 3), bool), ((6, 3), (12, 5))),
        nfz=np.zeros((12, 20), bool),
    )
    readings = []
    obs = _observations(wide, 1)

    def read(o):
        readings.append(o["coverage"].shape)
        return np.zeros((o["coverage"].shape[0], 5))

    symmetric_q_values(read, obs)
    assert readings == [(4 * 1, 12, 20)]  # one UAV: the four images stacked, read at once
    readings.clear()
    symmetric_q_values(read, _observations(wide, 3))
    assert readings == [(3, 12, 20)] * 4  # rows on one map: image by image, each shared


def test_image_by_image_gives_the_stacked_images_numbers_bit_for_bit():
    """A batch on one city map (obstacles, the city agent) read image by image, where the
    agent's shared features read each grid once, equals the stacked pass exactly; an episode
    rollout flies the same actions either way."""
    agent = load_agent("general-city")
    grid_map = load_map_set("city32-v1", first=1)[0]
    starts = np.repeat(np.flatnonzero(grid_map.landing.reshape(-1))[:3], 20)
    mdp = GridMDP(grid_map, starts.size, GridConfig(max_budget=150))
    mdp.restore(starts, np.tile(np.arange(60, 80), 3), np.zeros((starts.size, 1024), bool))
    for _ in range(3):
        obs = mdp.observation()
        assert shares_one_map(obs) and not shares_one_map({**obs, "map": np.array(obs["map"])})
        each = symmetric_q_values(agent.q_values, obs)
        stacked = symmetric_q_values(agent.q_values, {**obs, "map": np.array(obs["map"])})
        assert np.array_equal(each, stacked)
        mdp.step(each.argmax(axis=1))


def test_the_stacked_images_are_each_image_and_an_agent_reads_its_active_rows_of_each():
    """One forward pass over the eight images gives what eight passes gave, and an agent whose
    batch has finished rows reads only the active ones of every image."""
    torch.manual_seed(0)
    network = GeneralQNetwork(home_input=True, target_input=True)
    agent = GreedyAgent(network, 75.0, rules=[SymmetricQ()])
    obs = _observations(load_map("C"), 6)
    each = sum(
        agent.q_values(turn_observation(obs, s))[:, action_permutation(s)] for s in SYMMETRIES
    ) / len(SYMMETRIES)
    np.testing.assert_allclose(symmetric_q_values(agent.q_values, obs), each, atol=1e-6)
    active = np.array([True, False, True, True, False, True])
    some = agent.act_active(obs, active)
    np.testing.assert_array_equal(some[active], each.argmax(axis=1)[active])


def test_map_images_are_the_distinct_ones():
    assert [m.name for m in map_images(load_map("A"))][:2] == ["A", "A~rot90"]
    assert len(map_images(load_map("A"))) == 8
    plain = GridMap(
        landing=np.pad(np.ones((2, 2), bool), 7),
        target=np.pad(np.ones((4, 4), bool), 6),
        nfz=np.zeros((16, 16), bool),
    )
    assert map_images(plain) == [plain]  # centred squares: every image is the map itself
    assert turn_map(plain, IDENTITY) is plain


def test_a_map_name_with_an_image_loads_the_turned_map_and_says_so():
    image = load_map("C~rot180")
    assert np.array_equal(image.nfz, np.rot90(load_map("C").nfz, 2))
    assert image.label == "C~rot180" and not image.bundled
    assert image.identity()["map_source"] == "bundled (C), image rot180"
    with pytest.raises(MapError, match="unknown map image 'rot45'.*mirror-rot270"):
        load_map("C~rot45")
    with pytest.raises(MapError, match="unknown map 'nosuch'"):
        load_map("nosuch~rot90")


def test_evaluate_flies_an_agent_with_symmetric_q_and_names_it(tmp_path, capsys):
    from cpp_mujoco.cli.main import main

    args = ["evaluate", "--map", "B~rot90", "--agent", "B", "--budget-step", "25"]
    assert main([*args, "--rule", "+symmetric-q", "--out", str(tmp_path)]) == 0
    assert "symmetric" in capsys.readouterr().out
    # without the rule the turned map is another map: flown only when asked
    assert main([*args, "--out", str(tmp_path)]) == 2
    assert "not on map B~rot90" in capsys.readouterr().err
    assert main([*args, "--any-map", "--out", str(tmp_path)]) == 0
    files = sorted(p.name for p in tmp_path.glob("*ddqn*.json"))
    assert files == ["grid_B_rot90_ddqn_B.json", "grid_B_rot90_ddqn_B_rules_symmetric-q.json"]
    data = {name: json.loads((tmp_path / name).read_text()) for name in files}
    symmetric = [d for d in data.values() if "symmetric" in str(d["policy"])]
    assert len(symmetric) == 1 and "d4-mean" in json.dumps(symmetric[0])
    assert symmetric[0]["map"] == "B~rot90" and symmetric[0]["episodes"] == 8 * 3
