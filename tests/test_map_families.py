"""The generator's scatter and field families, their held-out sets, and pools mixing families."""

import numpy as np
import pytest
from scipy import ndimage

from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.map_pool import MapPool
from cpp_mujoco.map_sets.generator import (
    FAMILIES,
    FieldConfig,
    GeneratorConfig,
    ScatterConfig,
    check_map,
    generate_from_seed,
)
from cpp_mujoco.map_sets.sets import generate_map_set, load_map_set, map_set_spec


@pytest.mark.parametrize("size", [16, 32])
def test_scatter_maps_have_many_small_blocks_and_a_tiny_pad(size):
    maps = [generate_from_seed(seed, size, family="scatter") for seed in range(12)]
    paper = [generate_from_seed(seed, size) for seed in range(12)]
    for m in maps:
        check_map(m)
        assert m.name.startswith(f"scatter{size}-s") and not m.has_obstacles
        assert m.landing.sum() <= 4 * size // 16  # a rectangle of 1..3 cells (2x2 at most)
        assert not (m.landing & m.nfz).any()
    blocks = [ndimage.label(m.nfz)[1] for m in maps]
    assert np.mean(blocks) > 2 * np.mean([ndimage.label(m.nfz)[1] for m in paper])
    biggest = max(np.bincount(ndimage.label(m.nfz)[0].ravel())[1:].max() for m in maps)
    assert biggest <= 4 * (size // 16) * 6  # small blocks (touching ones merge)


@pytest.mark.parametrize("size", [16, 32])
def test_field_maps_are_open_ground_with_target_patches(size):
    maps = [generate_from_seed(seed, size, family="field") for seed in range(12)]
    for m in maps:
        check_map(m)
        assert m.name.startswith(f"field{size}-s")
        assert m.nfz.mean() < 0.05  # at most one small block
        assert 0.1 <= m.target.mean() <= 0.5
    assert any(ndimage.label(m.target)[1] >= 2 for m in maps)  # patches, not one region


def test_the_families_are_configs_of_the_paper_draw():
    assert FAMILIES["scatter"] is ScatterConfig and FAMILIES["field"] is FieldConfig
    assert issubclass(ScatterConfig, GeneratorConfig) and issubclass(FieldConfig, GeneratorConfig)
    with pytest.raises(ValueError, match="unknown map family"):
        generate_from_seed(0, 16, family="forest")
    other = generate_from_seed(3, 16, family="field", target_share=(0.3, 0.35))
    assert other.name.startswith("field16-s3-")  # other options than the family's: named so


@pytest.mark.parametrize(
    ("name", "size", "family", "first_seed", "count"),
    [("scatter16-v1", 16, "scatter", 1_300_000, 50), ("scatter32-v1", 32, "scatter", 1_300_000, 30),
     ("field16-v1", 16, "field", 1_400_000, 50), ("field32-v1", 32, "field", 1_400_000, 30)],
)  # fmt: skip
def test_the_family_sets_regenerate_to_the_committed_digests(name, size, family, first_seed, count):
    spec = map_set_spec(name)
    assert (spec.size, spec.count, spec.first_seed) == (size, count, first_seed)
    assert dict(spec.options) == {"family": family}
    assert [m.digest for m in generate_map_set(spec)] == list(spec.digests)
    first = load_map_set(name, first=1)[0]
    assert first.name == f"{family}{size}-s{first_seed}"


def test_a_pool_of_several_families_takes_them_in_turn():
    pool = MapPool.generate((16,), 6, 10, family="paper+scatter+field")
    expected = [
        generate_from_seed(10 + i, 16, **({} if f == "paper" else {"family": f}))
        for i, f in enumerate(["paper", "scatter", "field"] * 2)
    ]
    assert [m.digest for m in pool.maps] == [m.digest for m in expected]
    assert [m.name for m in pool.maps][:3] == ["gen16-s10", "scatter16-s11", "field16-s12"]
    assert pool.identity()["generator"] == {"family": "paper+scatter+field"}
    single = MapPool.generate((16,), 3, 10)  # the default family: the maps of every run before
    assert [m.digest for m in single.maps] == [
        generate_from_seed(s, 16).digest for s in (10, 11, 12)
    ]


def test_a_training_mix_of_families_is_checked():
    config = GeneralTrainConfig(map_family="paper+scatter+field")
    assert config.generator_options() == {"family": "paper+scatter+field"}
    with pytest.raises(ValueError, match="obstacle_input"):
        GeneralTrainConfig(map_family="paper+city")
    assert GeneralTrainConfig(map_family="paper+city", obstacle_input=True).map_family
    for bad in ("paper+forest", "paper+paper", "paper+", ""):
        with pytest.raises(ValueError, match="map_family"):
            GeneralTrainConfig(map_family=bad)
    with pytest.raises(ValueError, match="door_walls"):
        GeneralTrainConfig(map_family="paper+field", door_walls=0.5)
