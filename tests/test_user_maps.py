"""A user's own map: read as drawn (pixels per cell, background), flown with its size class's
budgets, and never flown by an agent trained on another map unless the user says so."""

import json

import numpy as np
import pytest
from PIL import Image

from cpp_mujoco.agent import load_agent
from cpp_mujoco.cli.main import main
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.maps import GridMap, MapError, load_map
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.protocol.policy import MapMismatchError
from cpp_mujoco.review import recording_tools


def _drawn(grid_map, pixels: int) -> Image.Image:
    """The map as a person draws it: every cell a block of ``pixels`` × ``pixels``."""
    rgb = grid_map.to_rgb()
    return Image.fromarray(np.kron(rgb, np.ones((pixels, pixels, 1), dtype=rgb.dtype)))


def test_a_map_drawn_at_ten_pixels_a_cell_is_refused_naming_the_option(tmp_path):
    path = tmp_path / "site.png"
    _drawn(load_map("B"), 10).save(path)
    with pytest.raises(MapError, match=r"10 pixels per cell \(a 16x16-cell map\).*cell_pixels=10"):
        load_map(path)
    read = load_map(path, cell_pixels=10)
    assert read.digest == load_map("B").digest and read.shape == (16, 16)
    # every pixel a cell, when the user says so: a 160x160 map
    assert load_map(path, cell_pixels=1).shape == (160, 160)
    with pytest.raises(MapError, match="cell_pixels=3 does not divide the 160x160 image"):
        load_map(path, cell_pixels=3)
    # a cell of two colours is not a cell
    rgb = np.asarray(Image.open(path)).copy()
    rgb[3, 15] = (0, 0, 255)
    Image.fromarray(rgb).save(path)
    with pytest.raises(MapError, match=r"cell \(row 0, col 1\) holds pixels of different colours"):
        load_map(path, cell_pixels=10)


def test_the_maps_the_package_ships_and_generates_are_read_pixel_per_cell(tmp_path):
    # a map whose every 4x4 block happened to be one colour would be refused: none is
    maps = [load_map(n) for n in "ABC"] + [generate_from_seed(s, 32) for s in range(10)]
    for i, grid_map in enumerate(maps):
        grid_map.save(tmp_path / f"{i}.png")
        assert load_map(tmp_path / f"{i}.png").digest == grid_map.digest


def test_a_map_drawn_on_white_says_the_format(tmp_path):
    path = tmp_path / "white.png"
    rgb = np.full((16, 16, 3), 255, np.uint8)
    rgb[0, 0] = (0, 0, 255)
    rgb[5, 5] = (0, 255, 0)
    Image.fromarray(rgb).save(path)
    with pytest.raises(MapError, match="pixels are white; a map is drawn on black"):
        load_map(path)
    read = load_map(path, white_background=True)  # white is empty then
    assert read.counts() == {"landing": 1, "target": 1, "nfz": 0, "obstacle": 0}


def test_maps_import_writes_a_map_drawn_elsewhere_in_the_map_format(tmp_path, capsys):
    # B drawn at 10 pixels a cell on white: imported, it is B, cell for cell
    rgb = load_map("B").to_rgb()
    rgb[(rgb == 0).all(axis=-1)] = 255
    Image.fromarray(np.kron(rgb, np.ones((10, 10, 1), dtype=rgb.dtype))).save(tmp_path / "b.png")
    args = ["maps", "import", str(tmp_path / "b.png"), "--out", str(tmp_path / "B.png")]
    assert main([*args, "--cell-pixels", "10", "--white-background"]) == 0
    assert load_map(tmp_path / "B.png").digest == load_map("B").digest
    assert "16x16 cells" in capsys.readouterr().out
    # an existing map is never replaced unless asked; the source is read before anything
    before = (tmp_path / "B.png").read_bytes()
    assert main([*args, "--cell-pixels", "10", "--white-background"]) == 2
    assert "exists; --overwrite replaces it" in capsys.readouterr().err
    assert main([*args, "--cell-pixels", "10", "--overwrite"]) == 2  # on white, unsaid
    assert (tmp_path / "B.png").read_bytes() == before
    # ASCII text
    (tmp_path / "t.txt").write_text("L.T\n.NY\n")
    assert main(["maps", "import", str(tmp_path / "t.txt"), "--out", str(tmp_path / "t.png")]) == 0
    assert load_map(tmp_path / "t.png").digest == GridMap.from_ascii(["L.T", ".NY"]).digest
    (tmp_path / "bad.txt").write_text("L.T\n.QY\n")
    assert (
        main(["maps", "import", str(tmp_path / "bad.txt"), "--out", str(tmp_path / "x.png")]) == 2
    )
    assert "unknown map character 'Q' at (row 1, col 1)" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()


def test_a_single_map_flies_its_size_class_budgets():
    big = generate_from_seed(7, 32)
    result = evaluate(make_planner("safe-greedy"), big, budget_step=50)
    assert result.conditions["budgets"] == {"min": 50, "max": 150, "step": 50}
    assert result.conditions["grid_config"]["max_budget"] == 150
    # the bundled 16x16 maps keep the paper's 25..75
    assert evaluate(make_planner("random"), "C", budget_step=25).conditions["budgets"] == {
        "min": 25, "max": 75, "step": 25
    }  # fmt: skip


def test_an_agent_of_one_map_is_refused_on_another_unless_asked():
    agent = load_agent("A")
    with pytest.raises(MapMismatchError, match=r"trained on map 'A' .* not on map B"):
        evaluate(agent, "B", budgets=[30])
    result = evaluate(agent, "B", budgets=[30], any_map=True)
    assert "not on map B" in result.conditions["off_its_map"]
    assert "off_its_map" not in evaluate(agent, "A", budgets=[30]).conditions
    # a file from before the digest names its bundled map, whose cells it was trained on
    assert load_agent("A").metadata["map_digest"] == load_map("A").digest
    # the general agent flies any map
    assert "off_its_map" not in evaluate(load_agent("general"), "B", budgets=[30]).conditions


def test_the_command_line_refuses_before_anything_is_written(tmp_path, capsys):
    out = tmp_path / "ev"
    assert main(["evaluate", "--map", "B", "--agent", "A", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "trained on map 'A'" in err and "--any-map" in err and not out.exists()
    argv = ["evaluate", "--map", "B", "--agent", "A", "--any-map", "--budget-step", "25"]
    assert main([*argv, "--out", str(out), "--no-progress"]) == 0
    (path,) = [p for p in out.glob("grid_B_*.json") if "tables" not in p.name]
    stored = json.loads(path.read_text())
    assert "not on map B" in stored["conditions"]["off_its_map"]
    fly = ["fly", "--map", "C", "--agent", "A", "--backend", "grid", "--budget", "20"]
    assert main(fly) == 2 and "trained on map 'A'" in capsys.readouterr().err


def test_fly_on_a_users_map_names_the_general_agent(tmp_path, capsys):
    path = tmp_path / "site.png"
    generate_from_seed(11).save(path)
    assert main(["fly", "--map", str(path), "--backend", "grid"]) == 2
    assert "--agent general" in capsys.readouterr().err
    drawn = tmp_path / "drawn.png"
    _drawn(load_map(path), 8).save(drawn)
    assert main(["maps", "draw", "--map", str(drawn), "--out", str(tmp_path / "m")]) == 2
    assert "--cell-pixels 8" in capsys.readouterr().err
    argv = ["maps", "draw", "--map", str(drawn), "--cell-pixels", "8"]
    assert main([*argv, "--out", str(tmp_path / "m")]) == 0


def test_the_recording_hint_is_a_command_that_runs_here(monkeypatch, tmp_path):
    script = recording_tools.rerun_cli()
    monkeypatch.setattr(recording_tools.shutil, "which", lambda name: None)  # not on PATH
    command = recording_tools.open_command(tmp_path / "a.rrd")
    exe = command.split()[0]
    assert exe != "rerun" and str(script).endswith(exe)
    monkeypatch.setattr(recording_tools.shutil, "which", lambda name: script)
    assert recording_tools.open_command("a.rrd") == "rerun a.rrd"


def test_a_result_prints_as_its_figures_not_its_arrays():
    result = evaluate(make_planner("safe-greedy"), "C", budget_step=25)
    text = repr(result)
    assert text.startswith("EvaluationResult(map C (") and "safe-greedy" in text
    assert f"{result.landed.size} episodes" in text and "landing 100.00%" in text
    assert len(text) < 200 and "array" not in text
