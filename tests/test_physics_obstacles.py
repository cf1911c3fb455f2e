"""Obstacles in physics: the arena's boxes, the crash into one, the camera's rays past them, the
drawn scenery and recording, and the physics vs grid coverage comparison."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.grid.actions import EAST, LAND, NORTH, SOUTH, WEST
from cpp_mujoco.maps import GridMap
from cpp_mujoco.missions.mission import fly_mission
from cpp_mujoco.physics.action import HOVER, MOVE
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.flight import Flight
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.physics.obstacles import OBSTACLE_GROUP, obstacle_boxes, rectangles
from cpp_mujoco.physics.occlusion_check import compare_coverage
from cpp_mujoco.physics.view.scenery import Scenery
from cpp_mujoco.planners.safe_greedy import SafeGreedyPlanner
from tests.test_review import rrd_entities

CONFIG = PhysicsConfig()
# a 2×2 building block, a lone building, a run of two low obstacles
BLOCKS = GridMap.from_ascii("""
    L.....
    .BB.O.
    .BB.O.
    B..T..
""")


def _flight(grid_map: GridMap, fov_side: int = 3) -> Flight:
    model = compile_arena(build_arena(grid_map, CONFIG, fov_side))
    coverage = np.zeros((1, grid_map.target.size), dtype=bool)
    return Flight(model, grid_map, CONFIG, 1, coverage)


def _hover_sees(grid_map: GridMap, cell: tuple[int, int], fov_side: int = 3) -> np.ndarray:
    """(H, W) cells the camera marks over ``cell`` in one hover (frames at its start, every
    0.1 s and its end)."""
    f = _flight(grid_map, fov_side)
    f.reset(0, *cell, 1e9, np.random.default_rng(0))
    r = f.fly_one(HOVER, cell[0] * grid_map.shape[1] + cell[1])
    assert r.failure is None
    return f.coverage[0].reshape(grid_map.shape).copy()


def test_rectangles_cover_the_mask_exactly_once():
    rng = np.random.default_rng(3)
    for _ in range(50):
        mask = rng.random((7, 9)) < 0.4
        count = np.zeros(mask.shape, dtype=int)
        for r0, r1, c0, c1 in rectangles(mask):
            count[r0 : r1 + 1, c0 : c1 + 1] += 1
        assert (count == mask).all()
    assert rectangles(np.ones((3, 4), dtype=bool)) == [(0, 2, 0, 3)]  # one block, one box


def test_the_arena_has_one_box_per_block_at_its_place_and_height():
    model = compile_arena(build_arena(BLOCKS, CONFIG))
    geo = GridGeometry.of(BLOCKS, CONFIG.cell_size)
    boxes = {model.geom(g).name: g for g in range(model.ngeom) if model.geom_group[g] == 1}
    assert sorted(boxes) == ["building_0", "building_1", "low_obstacle_2"]
    block, lone, low = (boxes[n] for n in ("building_0", "building_1", "low_obstacle_2"))
    for g, (r, c), (half_x, half_y), height in (
        (block, (1.5, 1.5), (4.0, 4.0), CONFIG.building_height_m),
        (lone, (3, 0), (2.0, 2.0), CONFIG.building_height_m),
        (low, (1.5, 4), (2.0, 4.0), CONFIG.low_obstacle_height_m),
    ):
        assert model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
        np.testing.assert_allclose(model.geom_pos[g], (*geo.cell_center(r, c), height / 2))
        np.testing.assert_allclose(model.geom_size[g], (half_x, half_y, height / 2))
        assert model.geom_contype[g] == model.geom_conaffinity[g] == 0  # the flight's check
        assert model.geom_group[g] == OBSTACLE_GROUP
    assert CONFIG.building_height_m > CONFIG.altitude > CONFIG.low_obstacle_height_m + 2
    # a map without obstacles gets no box, and the flight neither check nor ray
    open_map = GridMap.from_ascii("L.....\n.NN...\n...T..")
    plain = compile_arena(build_arena(open_map, CONFIG))
    assert plain.ngeom == model.ngeom - 3
    f = _flight(open_map)
    assert f.obstacles is None and f.camera.occlusion is None


def test_obstacle_heights_are_checked_on_maps_with_obstacles():
    with pytest.raises(ValueError, match="building_height_m"):
        PhysicsConfig(building_height_m=0.0)
    with pytest.raises(ValueError, match=r"building_height_m \(5\) must be above the cruise"):
        obstacle_boxes(BLOCKS, PhysicsConfig(building_height_m=5.0))
    with pytest.raises(ValueError, match=r"low_obstacle_height_m \(4.5\) must be at most"):
        obstacle_boxes(BLOCKS, PhysicsConfig(low_obstacle_height_m=4.5))
    # a config flown over open maps only may set any altitude
    PhysicsConfig(altitude=400.0)
    assert len(obstacle_boxes(BLOCKS, PhysicsConfig(altitude=20.0, building_height_m=30.0))) == 3


def test_a_drone_flown_into_a_building_crashes_on_the_contact_free_model():
    grid_map = GridMap.from_ascii("TTTTT\nTLLBT\nTTTTT")
    f = _flight(grid_map)
    f.reset(0, 1, 2, 1e9, np.random.default_rng(0))
    f.fly_one(HOVER, 7)
    assert f.air.airborne[0]  # at cruise the drone steps without contacts
    r = f.fly_one(MOVE, 8)
    assert r.failure == "hit a building" and not r.arrived
    x_face = GridGeometry.of(grid_map, CONFIG.cell_size).cell_center(1, 3)[0] - 2.0
    assert x_face - 0.5 < f.position(0)[0] < x_face  # stopped at the wall, not through it


def test_the_episode_of_a_drone_sent_into_a_building_ends_as_a_crash(monkeypatch):
    grid_map = GridMap.from_ascii("TTTTT\nTLLBT\nTTTTT")
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=grid_map).unwrapped
    env.reset(seed=0, options={"start": (1, 2), "budget": 10})
    # the safety controller refuses no-fly cells: let this one through, as a wrong map would
    monkeypatch.setattr(
        env.mdp.safety,
        "decide",
        lambda cells, actions: (np.array([8]), np.zeros(1, bool), np.zeros(1, bool)),  # fmt: skip
    )
    _, _, terminated, _, info = env.step(EAST)
    assert terminated and info["crashed"] and info["crash_reason"] == "hit a building"
    env.close()


def test_a_cell_behind_a_building_is_hidden_from_the_camera():
    """From (2, 1) the line to (2, 3), (1, 3) and (3, 3) crosses the building at (2, 2); on the
    same map without the building the camera sees them (a 5×5 field of view reaches them)."""
    walled = GridMap.from_ascii("TTTTT\nTTTTT\nTLBTT\nTTTTT\nTTTTT")
    open_ = GridMap.from_ascii("TTTTT\nTTTTT\nTL.TT\nTTTTT\nTTTTT")
    behind = [(2, 3), (1, 3), (3, 3)]
    seen_walled, seen_open = _hover_sees(walled, (2, 1), 5), _hover_sees(open_, (2, 1), 5)
    for cell in behind:
        assert seen_open[cell] and not seen_walled[cell], cell
    assert not seen_walled[2, 2]  # the building itself
    for cell in [(0, 0), (4, 0), (2, 0), (0, 2), (4, 2)]:  # beside it, in view
        assert seen_walled[cell], cell


def test_a_low_obstacle_under_the_camera_hides_the_ground_under_it():
    low = GridMap.from_ascii("TTT\nTOT\nLTT")
    seen = _hover_sees(low, (1, 1))
    assert not seen[1, 1]  # the box's top is between the camera and the cell's centre
    assert seen.sum() == 8  # the ground around it: the rays pass over the 2 m box
    assert _hover_sees(GridMap.from_ascii("TTT\nT.T\nLTT"), (1, 1)).all()


def test_compare_coverage_on_a_tall_building():
    """The hidden cells are the same for both; cells diagonal to the building, whose lines pass
    exactly through its corner, are left out of the targets (a tie, docs/physics.md)."""
    grid_map = GridMap.from_ascii("TTT.T\nTT.TT\nTLBTT\nTT.TT\nTTT.T")

    class Land:
        def act(self, obs):
            return np.full(len(obs["coverage"]), LAND)

    (gap,) = compare_coverage(grid_map, [(2, 1)], [10], Land(), fov_side=5)
    assert gap.actions == [LAND] and gap.crash_reason is None and gap.physics_steps == 1
    # 14 targets in the 5×5 view from (2, 1), three of them behind the building
    assert gap.grid_seen == gap.physics_seen == 11
    assert gap.extra == gap.missing == [] and gap.missing_share == gap.extra_share == 0.0
    gaps = compare_coverage(grid_map, [(2, 1)], [14], SafeGreedyPlanner(fov_side=5), fov_side=5)
    assert gaps[0].physics_steps == len(gaps[0].actions) and gaps[0].grid_seen > 11
    assert gaps[0].physics_seen == gaps[0].grid_seen + len(gaps[0].extra) - len(gaps[0].missing)


def test_the_scenery_leaves_out_the_no_fly_volume_inside_a_building():
    model = compile_arena(build_arena(BLOCKS, CONFIG))
    for scenery in (Scenery.from_model(model), Scenery(BLOCKS, CONFIG)):
        pos, _, _ = scenery.volumes()
        assert len(pos) == 0  # every no-fly cell of BLOCKS is a building
    plain = GridMap.from_ascii("L.N\n.T.")
    assert len(Scenery.from_model(compile_arena(build_arena(plain, CONFIG))).volumes()[0]) == 1


def test_the_recording_shows_the_obstacles_as_boxes(tmp_path):
    grid_map = GridMap.from_ascii("TTTT\nLTBT\nTTOT")
    fly_mission(SafeGreedyPlanner(), grid_map, budget=6, backend="grid", rrd=tmp_path / "o.rrd")
    assert "Boxes3D" in rrd_entities(tmp_path / "o.rrd")["/world/obstacles"]


def test_a_batch_sees_past_obstacles_what_each_drone_sees_alone():
    grid_map = GridMap.from_ascii("TTTTT\nTTBTT\nTLOTT\nTLTTT")
    route = [NORTH, EAST, EAST, SOUTH, SOUTH, WEST]  # over the low obstacle, beside the building
    alone = gym.make("cpp_mujoco/MuJoCo-v0", map=grid_map, fov_side=5).unwrapped
    alone.reset(seed=0, options={"start": (3, 1), "budget": 20})
    for action in route:
        alone.step(action)
    batch = gym.make_vec("cpp_mujoco/MuJoCo-v0", num_envs=2, map=grid_map, fov_side=5)
    batch.reset(seed=0, options={"start": np.array([[3, 1], [2, 1]]), "budget": np.array([20, 9])})
    for action in route:
        batch.step(np.array([action, LAND if action == NORTH else EAST]))
    np.testing.assert_array_equal(batch.unwrapped.mdp.coverage[0], alone.mdp.coverage[0])
    assert not alone.mdp.coverage[0].reshape(grid_map.shape)[1, 2]  # under the building's roof
    alone.close()
    batch.close()
