"""City maps (``family="city"``): the street grid of buildings cell by cell, low obstacles never
no-fly, no target under an obstacle, every landing pad reachable from every other, one map per
seed, and the held-out city sets regenerating to their committed digests."""

import numpy as np
import pytest
from scipy import ndimage

from cpp_mujoco.grid.graph import UNREACHABLE, build_graph
from cpp_mujoco.map_sets.city import CityConfig, draw_city
from cpp_mujoco.map_sets.generator import (
    check_map,
    config_from_options,
    describe,
    generate,
    generate_from_seed,
)
from cpp_mujoco.map_sets.sets import generate_map_set, load_map_set, map_set_spec
from cpp_mujoco.map_sets.size_classes import budget_range
from cpp_mujoco.maps import GridMap, MapError, load_map

# nothing drawn but the street grid: 3x3 blocks, streets 2 wide, every block built
_GRID_ONLY = {
    "street_width": (2, 2), "block_side": (3, 3), "building": 1.0, "low_building": 0.0,
    "alley": 0.0, "low_obstacles": (0, 0), "nfz_zones": (0, 0),
}  # fmt: skip


def _offset(mask_1d: np.ndarray) -> int:
    return int(np.flatnonzero(mask_1d)[0])


def test_the_street_grid_is_blocks_of_buildings_cell_by_cell():
    for seed in range(5):
        layers = draw_city(np.random.default_rng(seed), 32, CityConfig(**_GRID_ONLY))
        obstacle, nfz = layers["obstacle"], layers["nfz"]
        assert np.array_equal(obstacle, nfz)  # every obstacle a building: obstacle and no-fly
        top, left = _offset(obstacle.any(axis=1)), _offset(obstacle.any(axis=0))
        assert top <= 2 and left <= 2  # the grid starts at a drawn offset of 0..2
        r, c = np.indices((32, 32))
        # a block wherever both lines fall in a 3-cell band of the 5-cell period
        expected = ((r - top) % 5 < 3) & (r >= top) & ((c - left) % 5 < 3) & (c >= left)
        assert np.array_equal(obstacle, expected), seed
        # pads lie on streets only, targets neither on obstacles nor pads
        assert not (layers["landing"] & expected).any()
        assert not (layers["target"] & (obstacle | layers["landing"])).any()


def test_low_buildings_are_obstacles_one_may_fly_over_and_alleys_split_blocks():
    low = draw_city(np.random.default_rng(0), 32, CityConfig(**{**_GRID_ONLY, "low_building": 1}))
    assert low["obstacle"].sum() > 0 and not low["nfz"].any()  # obstacle only, never no-fly
    config = CityConfig(**{**_GRID_ONLY, "block_side": (5, 5), "alley": 1.0})
    for seed in range(3):
        layers = draw_city(np.random.default_rng(seed), 40, config)
        buildings = layers["obstacle"] & layers["nfz"]
        r, c = np.indices((40, 40))
        top, left = _offset(buildings.any(axis=1)), _offset(buildings.any(axis=0))
        blocks, _ = ndimage.label(
            ((r - top) % 7 < 5) & (r >= top) & ((c - left) % 7 < 5) & (c >= left)
        )
        whole = 0
        for box in ndimage.find_objects(blocks):
            block = buildings[box]
            if block.shape != (5, 5):
                continue  # cut by the map's edge
            whole += 1
            # one alley, a whole inner row or column of the block, splits it into two buildings
            empty = ~block
            rows, cols = np.flatnonzero(empty.all(axis=1)), np.flatnonzero(empty.all(axis=0))
            assert empty.sum() == 5 and len(rows) + len(cols) == 1
            assert 1 <= ([*rows, *cols][0]) <= 3
            assert ndimage.label(block)[1] == 2
        assert whole >= 25


def test_city_maps_are_one_map_per_seed_with_reachable_pads():
    maps = [generate_from_seed(seed, 32, family="city") for seed in range(6)]
    again = generate_from_seed(3, 32, family="city")
    assert again.digest == maps[3].digest and again.name == "city32-s3"
    assert len({m.digest for m in maps}) == 6
    for m in maps:
        check_map(m, pads=True)
        assert m.has_obstacles and not (m.target & m.obstacle).any()
        assert not (m.target & m.landing).any() and not (m.landing & (m.nfz | m.obstacle)).any()
        free = int((~m.obstacle & ~m.landing).sum())
        assert 0.2 * free - 1 <= m.target.sum() <= 0.5 * free + 1  # the drawn share of free cells
        # every pad reachable from every other: flight distances from the first landing cell
        g = build_graph(m)
        landing = np.flatnonzero(m.landing)
        assert (g.distance_from(landing[:1])[0, landing] < UNREACHABLE).all()
        # the pads: 2..4 squares of 1 or 2 cells a side, apart from one another
        labels, pads = ndimage.label(m.landing, structure=np.ones((3, 3)))
        assert 1 <= pads <= 4
        for k in range(1, pads + 1):
            rows, cols = np.nonzero(labels == k)
            side = rows.max() - rows.min() + 1
            assert side in (1, 2) and cols.max() - cols.min() + 1 == side
            assert rows.size == side * side


def test_pads_cut_apart_by_no_fly_cells_are_rejected():
    cut = GridMap.from_ascii(["L.N..", "..N.L", "T.N.."])
    with pytest.raises(MapError, match="landing pads are not reachable from one another"):
        check_map(cut, pads=True)
    with pytest.raises(MapError, match="not 4-connected: it has 2 separate parts"):
        check_map(cut)  # the paper-style rule: one landing zone
    check_map(GridMap.from_ascii(["L.O..", "..B.L", "T...."]), pads=True)  # around the building


def test_city_options_and_families():
    other = generate_from_seed(3, 32, family="city", landing_pads=(1, 1))
    assert other.name == f"city32-s3-{other.digest[:8]}"  # other options: the name says so
    assert generate(np.random.default_rng(0), 32, family="city").name.startswith("city32-")
    assert describe(CityConfig())["family"] == "city" and describe()["family"] == "paper"
    assert generate_from_seed(5, 16, family="paper").digest == generate_from_seed(5, 16).digest
    with pytest.raises(ValueError, match="unknown map family 'town'; known: paper, city"):
        config_from_options(family="town")
    with pytest.raises(ValueError, match="unknown city option.*'door_wall'"):
        generate_from_seed(1, 32, family="city", door_wall=1.0)
    with pytest.raises(ValueError, match="building is a probability"):
        CityConfig(building=1.5)
    with pytest.raises(ValueError, match="target_share must lie inside"):
        CityConfig(target_share=(0.0, 0.5))


def test_city_maps_keep_their_cells_through_a_file(tmp_path):
    grid_map = generate_from_seed(1_200_000, 50, family="city")
    grid_map.save(tmp_path / "c.png")
    loaded = load_map(tmp_path / "c.png")
    assert loaded.digest == grid_map.digest and loaded.has_obstacles
    assert np.array_equal(loaded.obstacle, grid_map.obstacle)


@pytest.mark.parametrize(("name", "size"), [("city32-v1", 32), ("city50-v1", 50)])
def test_the_city_sets_regenerate_to_the_committed_digests(name, size):
    spec = map_set_spec(name)
    assert (spec.size, spec.count, spec.first_seed) == (size, 30, 1_200_000)
    assert dict(spec.options) == {"family": "city"}
    maps = generate_map_set(spec)
    assert [m.digest for m in maps] == list(spec.digests)
    assert maps[0].name == f"city{size}-s1200000"
    assert [m.digest for m in load_map_set(name, first=2)] == list(spec.digests[:2])
    assert spec.identity()["generator_options"] == {"family": "city"}
    assert budget_range(50) == (150, 250) and spec.identity()["size_class_budgets"] == list(
        budget_range(size)
    )
