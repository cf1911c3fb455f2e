"""Map loading: the bundled maps and every rule a bad map file can break."""

import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from cpp_mujoco.maps import GridMap, MapError, bundled_maps, load_map


def test_bundled_maps_are_16x16_and_valid():
    assert {"A", "B", "C"} <= set(bundled_maps())
    for name in "ABC":
        m = load_map(name)
        assert m.shape == (16, 16)
        assert m.name == name
        assert not (m.landing & m.nfz).any()


def test_map_b_has_yellow_cells_and_map_a_a_large_landing_zone():
    b = load_map("B")
    assert (b.target & b.nfz).sum() >= 4
    a = load_map("A")
    assert a.landing.sum() >= 30


def test_png_round_trip_and_channel_meaning(tmp_path):
    m = GridMap.from_ascii(["LT.", "NY."])
    m.save(tmp_path / "m.png")
    rgb = np.asarray(Image.open(tmp_path / "m.png"))
    assert tuple(rgb[0, 0]) == (0, 0, 255)  # landing is blue
    assert tuple(rgb[0, 1]) == (0, 255, 0)  # target is green
    assert tuple(rgb[1, 0]) == (255, 0, 0)  # no-fly is red
    assert tuple(rgb[1, 1]) == (255, 255, 0)  # target + no-fly is yellow
    back = load_map(tmp_path / "m.png")
    for layer in ("landing", "target", "nfz"):
        np.testing.assert_array_equal(getattr(back, layer), getattr(m, layer))


def _png(path, rgb):
    Image.fromarray(np.asarray(rgb, dtype=np.uint8)).save(path)
    return path


def test_landing_and_nfz_overlap_names_first_cell(tmp_path):
    rgb = np.zeros((4, 5, 3))
    rgb[0, 0] = (0, 255, 0)
    rgb[2, 3] = (255, 0, 255)
    rgb[3, 1] = (255, 0, 255)
    with pytest.raises(MapError, match=r"overlap.*row 2, col 3"):
        load_map(_png(tmp_path / "x.png", rgb))


@pytest.mark.parametrize(
    ("pixel", "message"), [((0, 255, 0), "no landing"), ((0, 0, 255), "no target")]
)
def test_missing_layers(tmp_path, pixel, message):
    rgb = np.zeros((3, 3, 3))
    rgb[1, 1] = pixel
    with pytest.raises(MapError, match=message):
        load_map(_png(tmp_path / "x.png", rgb))


def test_wrong_mode_is_rejected(tmp_path):
    path = tmp_path / "gray.png"
    Image.fromarray(np.zeros((4, 4), dtype=np.uint8)).save(path)  # 2-D uint8: mode L
    with pytest.raises(MapError, match="mode 'L'"):
        load_map(path)


def test_truncated_and_garbage_files(tmp_path):
    good = GridMap.from_ascii(["LT"]).to_rgb()
    path = _png(tmp_path / "t.png", good)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(MapError, match="unreadable or truncated"):
        load_map(path)
    garbage = tmp_path / "g.png"
    garbage.write_text("not a png")
    with pytest.raises(MapError, match="unreadable"):
        load_map(garbage)


def test_absurd_size_unknown_name_and_missing_file(tmp_path):
    with pytest.raises(MapError, match="exceeds"):
        load_map(_png(tmp_path / "big.png", np.zeros((300, 300, 3))))
    with pytest.raises(MapError, match="unknown map 'Z'.*A, B, C"):
        load_map("Z")
    with pytest.raises(MapError, match="no such map file"):
        load_map(tmp_path / "missing.png")


def test_layers_must_agree_in_shape():
    with pytest.raises(MapError, match="different shapes"):
        GridMap(landing=np.ones((2, 2)), target=np.ones((2, 3)), nfz=np.zeros((2, 2)))
    with pytest.raises(MapError, match="unknown map character"):
        GridMap.from_ascii(["LQ"])


def test_layers_are_read_only():
    m = load_map("A")
    with pytest.raises(ValueError):
        m.target[0, 0] = True


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _png_header_only(width: int, height: int) -> bytes:
    """A PNG whose IHDR claims width×height RGB pixels, with no pixel data behind it."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IEND", b"")


def test_decompression_bomb_png_is_a_map_error_naming_the_limit(tmp_path):
    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(_png_header_only(100_000, 100_000))
    with pytest.raises(Image.DecompressionBombError):  # what PIL alone does with it
        Image.open(bomb)
    with pytest.raises(MapError, match=r"100000x100000 .*limit of 1\.\.256 cells per side"):
        load_map(bomb)


def test_any_pil_failure_is_a_map_error(tmp_path):
    # a GIF (no PNG header to read first) whose size trips PIL's own bomb check
    gif = tmp_path / "bomb.png"
    screen = struct.pack("<HHBBB", 65535, 65535, 0, 0, 0)
    frame = b"," + struct.pack("<HHHHB", 0, 0, 65535, 65535, 0) + b"\x08\x00;"
    gif.write_bytes(b"GIF89a" + screen + frame)
    with pytest.raises(MapError, match="too large"):
        load_map(gif)


def test_maps_over_the_size_limit_are_refused_before_allocating(tmp_path):
    with pytest.raises(MapError, match=r"257x3 cells exceeds the map size limit of 1\.\.256"):
        GridMap(landing=np.ones((257, 3)), target=np.ones((257, 3)), nfz=np.zeros((257, 3)))
    huge = np.broadcast_to(np.zeros((), dtype=bool), (100_000, 100_000))  # a view: no memory
    with pytest.raises(MapError, match="limit of 1..256"):
        GridMap(landing=huge, target=huge, nfz=huge)
    with pytest.raises(MapError, match="limit of 1..256"):
        load_map(_png(tmp_path / "tall.png", np.zeros((1, 257, 3))))
    rgb = np.zeros((256, 256, 3))
    rgb[0, 0], rgb[5, 5] = (0, 0, 255), (0, 255, 0)
    assert load_map(_png(tmp_path / "max.png", rgb)).shape == (256, 256)
