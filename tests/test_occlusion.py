"""Obstacles hide what the camera sees: the line-of-sight rule cell by cell, and its users."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.grid.coverage import square_fov_cells, view_cells
from cpp_mujoco.grid.graph import build_graph, graph_from_observation
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.grid.occlusion import visible_squares
from cpp_mujoco.maps import GridMap, MapError, load_map


def _shadow_reference(obstacle: np.ndarray) -> np.ndarray:
    """(H, W, H, W): [y0, x0] the cells in sight from (y0, x0) over the whole map — the lineage's
    rule written out straightforwardly: a Bresenham line to every border cell, stopped by the
    first obstacle; nothing from above an obstacle."""
    h, w = obstacle.shape
    seen = np.zeros((h, w, h, w), dtype=bool)
    border = [(0, x) for x in range(w)] + [(h - 1, x) for x in range(w)]
    border += [(y, 0) for y in range(h)] + [(y, w - 1) for y in range(h)]
    for y0 in range(h):
        for x0 in range(w):
            if obstacle[y0, x0]:
                continue
            seen[y0, x0, y0, x0] = True
            for y1, x1 in border:
                x_dist, y_dist = abs(x1 - x0), -abs(y1 - y0)
                x_step, y_step = (1 if x1 > x0 else -1), (1 if y1 > y0 else -1)
                error, x, y = x_dist + y_dist, x0, y0
                while x != x1 or y != y1:
                    if 2 * error - y_dist > x_dist - 2 * error:
                        error += y_dist
                        x += x_step
                    else:
                        error += x_dist
                        y += y_step
                    if obstacle[y, x]:
                        break
                    seen[y0, x0, y, x] = True
    return seen


def _square_of(seen: np.ndarray, side: int) -> np.ndarray:
    """The reference's sight cut to each cell's square, as (H·W, side²) slots."""
    h, w = seen.shape[:2]
    cells, valid = square_fov_cells((h, w), side)
    flat = seen.reshape(h * w, h * w)
    return valid & flat[np.arange(h * w)[:, None], cells]


@pytest.mark.parametrize("side", [3, 5])
def test_the_rule_equals_a_straightforward_reference_on_random_maps(side):
    rng = np.random.default_rng(side)
    positions = 0
    for _ in range(20):
        h, w = (int(v) for v in rng.integers(5, 15, size=2))
        obstacle = rng.random((h, w)) < rng.uniform(0.05, 0.35)
        expected = _square_of(_shadow_reference(obstacle), side)
        np.testing.assert_array_equal(visible_squares(obstacle, side), expected)
        positions += h * w
    assert positions > 1000


def _view_from_centre(obstacles: list[tuple[int, int]]) -> set[tuple[int, int]]:
    """The (dx, dy) offsets hidden in a 5×5 view from the centre of an open 7×7 patch with
    obstacles at the (dx, dy) offsets given (x east, y south), the obstacles left out."""
    obstacle = np.zeros((7, 7), dtype=bool)
    for dx, dy in obstacles:
        obstacle[3 + dy, 3 + dx] = True
    sight = visible_squares(obstacle, 5)[3 * 7 + 3].reshape(5, 5)
    hidden = {(dx, dy) for dy in range(-2, 3) for dx in range(-2, 3) if not sight[dy + 2, dx + 2]}
    return hidden - set(obstacles)


def test_the_worked_examples():
    assert _view_from_centre([(1, 0)]) == {(2, -1), (2, 0), (2, 1)}
    assert _view_from_centre([(1, 1)]) == {(2, 2)}
    assert _view_from_centre([(2, 1)]) == set()
    assert _view_from_centre([]) == set()


def test_nothing_is_seen_from_above_an_obstacle_and_no_fly_does_not_block():
    m = GridMap.from_ascii("L....\n.NNN.\n.NON.\n.NNN.\n....T")
    cells, valid = view_cells(m, 3)
    centre = 2 * 5 + 2
    assert not valid[centre].any()  # over the low obstacle: nothing
    assert (cells[centre] == centre).all()  # marking its table marks no other cell
    corner = 0  # no-fly all around the obstacle: the corner sees its square's three cells
    assert valid[corner].sum() == 4


@pytest.mark.parametrize("shape", [(1, 1), (2, 7), (16, 16), (17, 9), (33, 32)])
@pytest.mark.parametrize("side", [1, 3, 5, 7])
def test_without_obstacles_the_view_is_the_square(shape, side):
    open_sight = visible_squares(np.zeros(shape, dtype=bool), side)
    np.testing.assert_array_equal(open_sight, square_fov_cells(shape, side)[1])


WALL = GridMap.from_ascii(
    """
L.......
........
...B....
..LBTT..
...BTT..
...B....
........
""",
    name="wall",
)
BEHIND = [3 * 8 + 4, 4 * 8 + 4]  # the targets just east of the wall


def test_the_mdp_neither_counts_nor_marks_a_hidden_target():
    mdp = GridMDP(WALL, 1, GridConfig(fov_side=5))
    mdp.reset(np.random.default_rng(0), start=(3, 2), budget=30)  # west of the wall
    mdp.step(np.array([2]))  # south to (4, 2): the targets at col 4 are in the square, hidden
    assert mdp.seen_targets[0] == 0
    assert not mdp.coverage[0, BEHIND].any()  # not marked either: seen later, they count
    assert not mdp.coverage[0, 4 * 8 + 3]  # the building itself is never seen
    for action in (0, 0, 0, 1, 1):  # north to (1, 2), east round the wall's end to (1, 4)
        mdp.step(np.array([action]))
    assert mdp.coverage[0, BEHIND[0]] and mdp.seen_targets[0] >= 2
    cells, valid = view_cells(WALL, 5)
    path = [4 * 8 + 2, 3 * 8 + 2, 2 * 8 + 2, 1 * 8 + 2, 1 * 8 + 3, 1 * 8 + 4]
    seen = {int(c) for p in path for c in cells[p][valid[p]]}
    assert mdp.seen_targets[0] == len(seen & set(np.flatnonzero(WALL.target).tolist()))
    np.testing.assert_array_equal(np.flatnonzero(mdp.coverage[0]), sorted(seen))


def test_planners_and_bounds_see_through_the_same_rule():
    g = build_graph(WALL, 5)
    assert g.new_per_move >= 5
    cells, valid = view_cells(WALL, 5)
    np.testing.assert_array_equal(g.fov_valid, valid)
    # the bound per move holds for every accepted move of random obstacle maps
    rng = np.random.default_rng(7)
    for _ in range(5):
        obstacle = rng.random((9, 11)) < 0.25
        landing = np.zeros_like(obstacle)
        landing[0, 0], obstacle[0, 0] = True, False
        target = ~obstacle & (rng.random(obstacle.shape) < 0.5)
        target[8, 10], obstacle[8, 10] = True, False
        m = GridMap(landing=landing, target=target, nfz=np.zeros_like(obstacle), obstacle=obstacle)
        g = build_graph(m, 3)
        for p in range(m.landing.size):
            seen_p = set(g.fov_cells[p][g.fov_valid[p]].tolist())
            for a in range(4):
                if g.safety.accepted[p, a]:
                    q = g.safety.next_cell[p, a]
                    new = set(g.fov_cells[q][g.fov_valid[q]].tolist()) - seen_p
                    assert len(new) <= g.new_per_move


def test_the_observation_carries_obstacles_only_where_the_map_has_them():
    env = gym.make("cpp_mujoco/Grid-v0", map=WALL)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    np.testing.assert_array_equal(obs["obstacle"], WALL.obstacle.astype(np.int8))
    g = graph_from_observation(obs, 3)
    assert g.grid_map.digest == WALL.digest
    plain, _ = gym.make("cpp_mujoco/Grid-v0", map="A").reset(seed=0)
    assert "obstacle" not in plain


def test_an_agent_without_an_obstacle_input_does_not_fit_an_obstacle_map():
    from cpp_mujoco.agent import load_agent

    reason = load_agent("general").fits(WALL)
    assert reason is not None and "obstacle" in reason
    assert load_agent("general").fits(load_map("A")) is None


def test_obstacle_maps_round_trip_and_bad_ones_are_refused(tmp_path):
    WALL.save(tmp_path / "wall.png")
    read = load_map(tmp_path / "wall.png")
    assert read.digest == WALL.digest
    np.testing.assert_array_equal(read.obstacle, WALL.obstacle)
    np.testing.assert_array_equal(read.nfz, WALL.nfz)  # a building is no-fly too
    plain = load_map("A")
    assert plain.digest == "242dcad1db2a" and not plain.has_obstacles
    with pytest.raises(MapError, match=r"target cell\(s\) under an obstacle"):
        GridMap(landing=WALL.landing, target=WALL.target | WALL.obstacle, nfz=WALL.nfz,
                obstacle=WALL.obstacle)  # fmt: skip
    with pytest.raises(MapError, match=r"landing cell\(s\) under an obstacle"):
        GridMap(landing=WALL.landing, target=WALL.target, nfz=WALL.nfz, obstacle=WALL.landing)
    with pytest.raises(MapError, match="unknown map character 'X'"):
        GridMap.from_ascii("LX\nT.")


def test_the_exact_planner_plans_with_what_the_camera_can_see():
    from cpp_mujoco.planners.optimal import beam_missions, solve_episodes
    from cpp_mujoco.planners.optimal_solver import SolverOptions

    starts = np.array([(0, 0), (3, 2), (0, 0), (3, 2)])
    budgets = np.array([12, 14, 20, 24])
    entries = solve_episodes(WALL, starts, budgets, SolverOptions(time_limit_s=30))
    g = build_graph(WALL, 3)
    cells = starts[:, 0] * 8 + starts[:, 1]
    beams = beam_missions(WALL, cells, budgets, 3)
    seen0 = np.zeros(g.num_cells, dtype=bool)
    for entry, cell, beam in zip(entries, cells, beams, strict=True):
        assert entry["status"] == "optimal"
        seen, landed = g.fly(int(cell), np.asarray(entry["actions"]), seen0)
        assert landed and seen == entry["seen"]  # the MDP's own count, occlusion included
        assert seen >= g.fly(int(cell), beam, seen0)[0]
    assert entries[-1]["seen"] == int(WALL.target.sum())  # round the wall: every target


def test_a_planner_plans_with_the_camera_the_episodes_fly():
    from cpp_mujoco.planners import make_planner
    from cpp_mujoco.protocol.evaluate import evaluate

    five = {"fov_side": 5}
    with pytest.raises(ValueError, match="plans with a 3x3 view, the episodes see 5x5"):
        evaluate(make_planner("safe-greedy"), WALL, budgets=[20], env_kwargs=five)
    result = evaluate(make_planner("beam-search", fov_side=5), WALL, budgets=[20, 30],
                      env_kwargs=five)  # fmt: skip
    assert result.conditions["fov_side"] == 5 and result.landing_ratio == 1.0
