"""The ``cpp-mujoco`` command: outputs written; bad input answered with a message, no traceback."""

import json

import pytest

from cpp_mujoco.cli import build_parser, main


def test_every_subcommand_has_help(capsys):
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices  # noqa: SLF001
    for name in commands:
        with pytest.raises(SystemExit) as exit_info:
            main([name, "--help"])
        assert exit_info.value.code == 0
        assert "usage: cpp-mujoco" in capsys.readouterr().out


def test_evaluate_writes_json_and_figures(tmp_path, capsys):
    code = main(["evaluate", "--map", "C", "--planner", "safe-greedy", "--out", str(tmp_path)])
    assert code == 0
    out = capsys.readouterr().out
    assert "safe-greedy" in out and "100.00%" in out
    data = json.loads((tmp_path / "grid_C_safe-greedy.json").read_text())
    assert data["landing_ratio"] == 1.0 and data["episodes"] == 12 * 51
    assert (tmp_path / "grid_C_coverage.png").stat().st_size > 10_000
    assert (tmp_path / "grid_C_safe-greedy_trajectories.png").stat().st_size > 10_000


def test_maps_draws_figures(tmp_path, capsys):
    assert main(["maps", "B", "--out", str(tmp_path)]) == 0
    assert "B" in capsys.readouterr().out
    assert (tmp_path / "map_B.png").is_file()


def test_bad_input_is_a_message_not_a_traceback(tmp_path, capsys):
    assert main(["evaluate", "--map", "Z", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "unknown map 'Z'" in err and "Traceback" not in err
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"\x89PNG garbage")
    assert main(["maps", str(broken), "--out", str(tmp_path)]) == 2
    assert "unreadable" in capsys.readouterr().err
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["maps", "A", "--out", str(blocker / "sub")]) == 2
    assert "cannot create output folder" in capsys.readouterr().err
