"""The lineage's maps (uavSim): its colours read cell by cell into ours, targets from a PNG (those
under an obstacle dropped and counted) or drawn by seed over an exact share of the free cells,
every bad input refused with nothing written, and ``maps import --format uavsim``."""

import math

import numpy as np
import pytest
from PIL import Image
from scipy import ndimage

from cpp_mujoco.cli.main import main
from cpp_mujoco.maps import GridMap, MapError, load_map
from cpp_mujoco.maps.lineage import TargetShapes, import_uavsim, random_targets, read_uavsim

# uavSim's colours, one letter a cell: . empty, N no-fly (R), O obstacle (G), B building (R+G),
# L landing (B); the values are theirs: 1 in some files, 255 in others, both count
_RGB = {".": (0, 0, 0), "N": (1, 0, 0), "O": (0, 255, 0), "B": (255, 1, 0), "L": (0, 0, 1)}
_BRIGHT = {".": (0, 0, 0), "N": (255, 0, 0), "O": (0, 1, 0), "B": (1, 255, 0), "L": (0, 0, 255)}
_MAP = [
    "LL..NN",
    "LL..NN",
    "..OO..",
    "BB....",
    "BB.O..",
]
_TARGETS = [  # 1 = target: two under the building, one under the low obstacle, one on landing
    "010011",
    "000000",
    "000000",
    "110000",
    "000110",
]
# ours: T target, Y target + no-fly, G landing + target, O low obstacle, B building
_EXPECTED = [
    "LG..YY",
    "LL..NN",
    "..OO..",
    "BB....",
    "BB.OT.",
]


def _image(rows: list[str], colours: dict, path, alpha: bool = False) -> None:
    rgb = np.array([[colours[ch] for ch in row] for row in rows], dtype=np.uint8)
    if alpha:  # alpha means nothing to uavSim: a transparent pixel is its colour
        rgb = np.concatenate([rgb, np.zeros((*rgb.shape[:2], 1), np.uint8)], axis=-1)
    Image.fromarray(rgb).save(path)


def _targets(rows: list[str], path, value: int = 1) -> None:
    grey = np.array([[int(ch) * value for ch in row] for row in rows], dtype=np.uint8)
    Image.fromarray(grey).save(path)  # mode L


def _same(a: GridMap, b: GridMap) -> None:
    for layer in ("landing", "target", "nfz", "obstacle"):
        assert np.array_equal(getattr(a, layer), getattr(b, layer)), layer


@pytest.mark.parametrize(("colours", "alpha"), [(_RGB, False), (_BRIGHT, False), (_RGB, True)])
def test_a_uavsim_map_and_its_target_png_read_cell_by_cell(tmp_path, colours, alpha):
    _image(_MAP, colours, tmp_path / "city.png", alpha)
    _targets(_TARGETS, tmp_path / "targets.png", value=1 if alpha else 255)
    read = import_uavsim(tmp_path / "city.png", targets=tmp_path / "targets.png")
    expected = GridMap.from_ascii(_EXPECTED)
    _same(read.grid_map, expected)
    assert read.grid_map.digest == expected.digest and read.grid_map.name == "city"
    assert read.dropped_targets == 3 and not read.generated
    assert "3 under an obstacle dropped" in read.describe()
    # the building is obstacle and no-fly, the low obstacle obstacle only
    assert read.grid_map.nfz[3, 0] and read.grid_map.obstacle[3, 0]
    assert read.grid_map.obstacle[2, 2] and not read.grid_map.nfz[2, 2]


def _free_city(path) -> None:
    """A 20x20 uavSim map: 100 building cells in 3x3 blocks, 4 low obstacles, a landing zone of
    3 cells, the rest (293 cells) free."""
    r, c = np.indices((20, 20))
    cells = np.full((20, 20), ".")
    cells[np.isin(r % 6, (1, 2, 3)) & np.isin(c % 6, (1, 2, 3))] = "B"
    cells[(5, 11, 17, 0), (5, 0, 17, 4)] = "O"
    cells[18, 3:6] = "L"
    _image(["".join(row) for row in cells], _BRIGHT, path)


@pytest.mark.parametrize("fraction", [0.01, 0.3, 0.77, 1.0])
def test_drawn_targets_cover_the_share_exactly_by_seed_never_on_obstacle_or_landing(
    tmp_path, fraction
):
    _free_city(tmp_path / "m.png")
    maps = [read_uavsim(tmp_path / "m.png", target_fraction=fraction, seed=s) for s in range(4)]
    free = ~maps[0].obstacle & ~maps[0].landing
    assert int(free.sum()) == 293 and maps[0].counts()["obstacle"] == 104
    goal = max(1, math.floor(fraction * int(free.sum()) + 0.5))
    for m in maps:
        assert int(m.target.sum()) == goal  # the share, exactly (rounded to whole cells)
        assert not (m.target & (m.obstacle | m.landing)).any()
    # the same seed, the same targets; other seeds, other targets (but all of them at 1.0)
    again = read_uavsim(tmp_path / "m.png", target_fraction=fraction, seed=2)
    assert np.array_equal(again.target, maps[2].target)
    if fraction < 1.0:
        assert len({m.target.tobytes() for m in maps}) == 4
    else:
        assert all(np.array_equal(m.target, free) for m in maps)


def test_drawn_targets_are_patches_and_fill_scattered_free_cells():
    rng = np.random.default_rng(5)
    free = np.ones((32, 32), dtype=bool)
    target = random_targets(free, 0.3, rng)
    assert int(target.sum()) == round(0.3 * 1024)
    _, parts = ndimage.label(target)
    assert parts <= 16  # a few shapes, not scattered cells (307 cells)
    # free cells on a checkerboard: shapes keep missing them; the rest is filled beside the patches
    board = (np.add.outer(np.arange(20), np.arange(20)) % 2).astype(bool)
    few = TargetShapes(count=(1, 1), max_shapes=2)
    target = random_targets(board, 0.5, np.random.default_rng(1), few)
    assert int(target.sum()) == 100 and not (target & ~board).any()
    with pytest.raises(MapError, match="no free cell"):
        random_targets(np.zeros((4, 4), dtype=bool), 0.5, rng)


@pytest.mark.parametrize(
    ("pixel", "message"),
    [
        (
            (7, 0, 255),
            r"1 landing \(blue\) cell\(s\) also no-fly \(red\), first at \(row 1, col 2\)",
        ),
        (
            (0, 3, 1),
            r"1 landing \(blue\) cell\(s\) also obstacle \(green\), first at \(row 1, col 2\)",
        ),
        ((0, 3, 0), "no landing cell"),
    ],
)
def test_bad_uavsim_maps_are_refused(tmp_path, pixel, message):
    rgb = np.zeros((3, 4, 3), np.uint8)
    rgb[1, 2] = pixel
    Image.fromarray(rgb).save(tmp_path / "bad.png")
    with pytest.raises(MapError, match=message):
        read_uavsim(tmp_path / "bad.png", target_fraction=0.5)


@pytest.mark.parametrize("fraction", [0.0, -0.1, 1.5, float("nan"), float("inf"), True, "0.5"])
def test_a_fraction_outside_zero_to_one_is_refused(tmp_path, fraction):
    _image(_MAP, _RGB, tmp_path / "m.png")
    with pytest.raises(MapError, match="target fraction"):
        read_uavsim(tmp_path / "m.png", target_fraction=fraction)


def test_targets_of_another_size_or_none_left_or_missing_are_refused(tmp_path):
    _image(_MAP, _RGB, tmp_path / "m.png")
    _targets(["01", "10"], tmp_path / "small.png")
    with pytest.raises(MapError, match="target PNG is 2x2 pixels, the map .* is 6x5"):
        read_uavsim(tmp_path / "m.png", targets=tmp_path / "small.png")
    under = ["000000", "000000", "001100", "110000", "110000"]  # all under obstacles
    _targets(under, tmp_path / "under.png")
    with pytest.raises(MapError, match=r"no target cell left \(6 under an obstacle dropped\)"):
        read_uavsim(tmp_path / "m.png", targets=tmp_path / "under.png")
    with pytest.raises(MapError, match="no such target PNG"):
        read_uavsim(tmp_path / "m.png", targets=tmp_path / "nope.png")
    with pytest.raises(MapError, match="neither given"):
        read_uavsim(tmp_path / "m.png")
    with pytest.raises(MapError, match="both given"):
        read_uavsim(tmp_path / "m.png", targets=tmp_path / "under.png", target_fraction=0.5)
    with pytest.raises(MapError, match="seed must be an integer"):
        read_uavsim(tmp_path / "m.png", target_fraction=0.5, seed=-1)


# ----------------------------------------------------------------------------------------- CLI
def test_maps_import_uavsim_writes_our_format(tmp_path, capsys):
    _image(_MAP, _RGB, tmp_path / "city.png")
    _targets(_TARGETS, tmp_path / "t.png")
    out = tmp_path / "maps" / "site.png"
    argv = ["maps", "import", str(tmp_path / "city.png"), "--format", "uavsim", "--out", str(out)]
    assert main([*argv, "--targets", str(tmp_path / "t.png")]) == 0
    printed = capsys.readouterr().out
    assert "3 under an obstacle dropped" in printed and "obstacle 7" in printed
    saved = load_map(out)
    _same(saved, GridMap.from_ascii(_EXPECTED))
    alpha = np.asarray(Image.open(out))[..., 3]  # obstacles are our alpha
    assert np.array_equal(alpha < 255, GridMap.from_ascii(_EXPECTED).obstacle)
    # drawn targets: the file is the function's map, seed for seed
    drawn = ["--target-fraction", "0.5", "--seed", "3", "--overwrite"]
    assert main([*argv, *drawn]) == 0
    assert "drawn over 0.5 of the free cells (seed 3)" in capsys.readouterr().out
    expected = read_uavsim(tmp_path / "city.png", target_fraction=0.5, seed=3)
    assert load_map(out).digest == expected.digest


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--format", "uavsim"], "a uavSim map keeps no targets"),
        (["--format", "uavsim", "--target-fraction", "nan"], "target fraction must lie in"),
        (["--format", "uavsim", "--target-fraction", "0"], "target fraction must lie in"),
        (["--format", "uavsim", "--target-fraction", "1.01"], "target fraction must lie in"),
        (["--format", "uavsim", "--targets", "SMALL"], "they must be the same size"),
        (["--format", "uavsim", "--seed", "2", "--targets", "SMALL"], "with --target-fraction"),
        (["--format", "uavsim", "--target-fraction", "0.5", "--cell-pixels", "2"], "format ours"),
        (["--target-fraction", "0.5"], "--target-fraction: only with --format uavsim"),
        (["--targets", "SMALL"], "--targets: only with --format uavsim"),
    ],
)
def test_maps_import_uavsim_refuses_bad_input_and_writes_nothing(tmp_path, capsys, extra, message):
    _image(_MAP, _RGB, tmp_path / "city.png")
    _targets(["01", "10"], tmp_path / "small.png")
    extra = [str(tmp_path / "small.png") if e == "SMALL" else e for e in extra]
    out = tmp_path / "out" / "site.png"
    assert main(["maps", "import", str(tmp_path / "city.png"), "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.splitlines()) == 1
    assert not out.exists() and not out.parent.exists()


def test_maps_import_uavsim_refuses_a_landing_on_no_fly_and_writes_nothing(tmp_path, capsys):
    rgb = np.zeros((3, 3, 3), np.uint8)
    rgb[0, 0] = (1, 0, 1)  # landing and no-fly, in uavSim's small values
    Image.fromarray(rgb).save(tmp_path / "m.png")
    out = tmp_path / "site.png"
    argv = ["maps", "import", str(tmp_path / "m.png"), "--format", "uavsim", "--out", str(out)]
    assert main([*argv, "--target-fraction", "0.5"]) == 2
    assert "landing (blue) cell(s) also no-fly (red)" in capsys.readouterr().err
    assert not out.exists() and list(tmp_path.iterdir()) == [tmp_path / "m.png"]
