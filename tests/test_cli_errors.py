"""The command line: one-line errors before anything runs, honest map labels, help, progress."""

import json
import shutil
import subprocess
import sys

import pytest

from cpp_mujoco import __version__
from cpp_mujoco.agent import BUNDLED_DIR
from cpp_mujoco.cli.main import build_parser, main
from cpp_mujoco.maps import GridMap, load_map

SMALL = GridMap.from_ascii(["LL.TT", "LL.TT", "....."], name="small")


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def _exit_code(argv) -> int:
    """main's return value, or the SystemExit code argparse raises."""
    try:
        return main(argv)
    except SystemExit as e:
        return e.code


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["fly", "--seed", "-1"], ["--seed", ">= 0", "-1"]),
        (["fly", "--budget", "0"], ["--budget", ">= 1"]),
        (["demo", "--budget-step", "0"], ["--budget-step", ">= 1"]),
        (["evaluate", "--map", "Z"], ["unknown map 'Z'"]),
    ],
)
def test_bad_option_is_one_line_and_exit_2(argv, words, capsys):
    assert _exit_code(argv) == 2
    line = _one_line(capsys.readouterr().err)
    assert all(w in line for w in words), line


@pytest.mark.parametrize("option", ["--rrd", "--video", "--onboard-video"])
def test_output_file_option_pointing_at_a_folder_fails_before_flying(tmp_path, option, capsys):
    code = main(["fly", "--map", "C", "--planner", "safe-greedy", option, str(tmp_path)])
    assert code == 2
    out, err = capsys.readouterr()
    assert out == ""  # nothing flew
    line = _one_line(err)
    assert option in line and "is a folder" in line


def test_missing_parent_folder_of_an_output_file_is_created(tmp_path, capsys):
    rrd = tmp_path / "new" / "deeper" / "m.rrd"
    code = main(["fly", "--map", "C", "--planner", "safe-greedy", "--backend", "grid",
                 "--budget", "30", "--rrd", str(rrd)])  # fmt: skip
    assert code == 0 and rrd.stat().st_size > 0


def test_a_run_folder_given_as_agent_names_the_checkpoint_inside(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    shutil.copyfile(BUNDLED_DIR / "A.pt", run / "best.pt")
    for argv in (
        ["fly", "--map", "A", "--agent", str(run)],
        ["evaluate", "--map", "A", "--agent", str(run), "--out", str(tmp_path)],
    ):
        assert main(argv) == 2
        line = _one_line(capsys.readouterr().err)
        assert "is a folder" in line and str(run / "best.pt") in line
        assert "weights_only" not in line


def test_a_user_map_has_no_default_agent(tmp_path, capsys):
    # a 16x16 user map saved as A.png used to be flown by the bundled agent of map A
    path = tmp_path / "A.png"
    b = load_map("B")
    GridMap(b.landing, b.target, b.nfz, name="A").save(path)
    assert main(["fly", "--map", str(path), "--backend", "grid"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "not a bundled map" in line and "--agent" in line


def test_evaluate_a_user_map_by_path_through_every_policy(tmp_path, capsys):
    # before: the second step of the first policy reloaded the map by name ("unknown map 'field7'")
    path = tmp_path / "maps" / "field7.png"
    path.parent.mkdir()
    SMALL.save(path)
    out = tmp_path / "out"
    code = main(["evaluate", "--map", str(path), "--planner", "safe-greedy", "random",
                 "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    for policy in ("safe-greedy", "random"):
        assert json.loads((out / f"grid_field7_{policy}.json").read_text())["map"] == "field7"
        assert (out / f"grid_field7_{policy}_trajectories.png").is_file()
    assert (out / "grid_field7_coverage.png").is_file()


def test_a_user_map_named_like_a_bundled_map_is_labelled_and_drawn_as_itself(
    tmp_path, capsys, monkeypatch
):
    import cpp_mujoco.review.plots as plots

    path = tmp_path / "A.png"
    SMALL.save(path)
    label = f"A-{load_map(path).digest[:8]}"
    drawn = []
    draw_map = plots.draw_map
    monkeypatch.setattr(plots, "draw_map", lambda ax, m, *a: drawn.append(m) or draw_map(ax, m, *a))
    code = main(["evaluate", "--map", str(path), "--planner", "safe-greedy", "--out",
                 str(tmp_path / "out")])  # fmt: skip
    assert code == 0
    table = capsys.readouterr().out
    row = next(line for line in table.splitlines() if line.startswith(label))
    assert row.split()[-2] == "-"  # no paper landing ratio: that is the bundled map A's
    data = json.loads((tmp_path / "out" / f"grid_{label}_safe-greedy.json").read_text())
    assert data["map"] == label and data["map_digest"] == SMALL.digest
    # the user's 4 landing cells, not bundled A's 36, × the budgets of its size class (5: 8..23)
    assert data["episodes"] == 4 * len(range(8, 24))
    assert not list((tmp_path / "out").glob("grid_A_*"))
    assert drawn and all(m.digest == SMALL.digest for m in drawn)  # figures of the user's map
    assert main(["maps", "draw", "--map", str(path), "--out", str(tmp_path / "maps")]) == 0
    assert (tmp_path / "maps" / f"map_{label}.png").is_file()


def test_every_option_has_help_and_states_its_default_at_most_once():
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices  # noqa: SLF001
    for name, sub in commands.items():
        if name == "train":  # its options are generated from TrainConfig in cli/train.py
            continue
        nested = [a for a in sub._actions if a.dest in ("maps_command", "site_command")]  # noqa: SLF001
        parsers = [sub, *(p for a in nested for p in a.choices.values())]
        for action in (a for p in parsers for a in p._actions):  # noqa: SLF001
            if action.dest == "help":
                continue
            assert action.help, f"{name} {action.option_strings or action.dest} has no help"
            text = action.help.replace("%(default)s", "")
            assert text.count("default") <= 1, f"{name} {action.option_strings}"
        # maps and site run for seconds, no progress bar to switch off
        quick = name in ("maps", "site")
        assert any(a.dest == "no_progress" for a in sub._actions) == (not quick), name  # noqa: SLF001


def test_version_through_python_m_cpp_mujoco():
    result = subprocess.run(
        [sys.executable, "-m", "cpp_mujoco", "--version"], capture_output=True, text=True
    )
    assert result.returncode == 0 and result.stdout.strip() == f"cpp-mujoco {__version__}"


@pytest.mark.parametrize(
    ("argv", "tty", "bar"),
    [
        ([], False, False),  # not a terminal: quiet
        ([], True, True),
        (["--no-progress"], True, False),
    ],
)
def test_progress_bars_only_on_a_terminal(tmp_path, capsys, monkeypatch, argv, tty, bar):
    path = tmp_path / "small.png"
    SMALL.save(path)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: tty)
    assert main(["evaluate", "--map", str(path), "--planner", "safe-greedy",
                 "--out", str(tmp_path), *argv]) == 0  # fmt: skip
    assert main(["fly", "--map", str(path), "--planner", "safe-greedy", "--backend", "grid",
                 "--budget", "8", "--start", "0,1", *argv]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert ("grid small" in err and "ep/s" in err) == bar, err  # the protocol's bar
    assert ("fly small" in err and "action" in err) == bar, err  # the mission's bar


# ------------------------------------------------------------------------------- --turbulence
TINY = GridMap.from_ascii(["L.T", "..."], name="tiny")  # one landing cell: one episode per budget


def test_turbulence_levels_are_the_models():
    from cpp_mujoco.cli.options import TURBULENCE_LEVELS
    from cpp_mujoco.physics.air.turbulence import LEVELS

    assert TURBULENCE_LEVELS == LEVELS


def test_the_parsers_planner_names_are_the_planners():
    from cpp_mujoco.cli.options import PLANNER_NAMES
    from cpp_mujoco.planners import PLANNERS

    assert PLANNER_NAMES == tuple(PLANNERS)


def test_the_parsers_solvers_are_the_exact_planners():
    from cpp_mujoco.cli.options import SOLVERS as NAMED
    from cpp_mujoco.planners.optimal_solver import SOLVERS

    assert NAMED == SOLVERS


def test_evaluate_in_mujoco_records_the_turbulence_it_flew(tmp_path, capsys, monkeypatch):
    import cpp_mujoco.protocol.evaluate as protocol

    # before: no --turbulence option; a run in turbulence could not be asked for from the CLI
    monkeypatch.setattr(protocol, "protocol_budgets", lambda config=None, step=1: [4])
    path = tmp_path / "tiny.png"
    TINY.save(path)
    out = tmp_path / "out"
    code = main(["evaluate", "--map", str(path), "--planner", "safe-greedy", "--backend", "mujoco",
                 "--workers", "1", "--turbulence", "moderate", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    data = json.loads((out / "mujoco_tiny_safe-greedy.json").read_text())
    assert data["episodes"] == 1
    assert data["conditions"]["physics_config"]["turbulence"] == "moderate"
    assert data["conditions"]["env_kwargs"]["turbulence"] == "moderate"


@pytest.mark.parametrize("command", ["evaluate", "fly"])
def test_an_unknown_turbulence_level_is_one_line_and_exit_2(command, capsys):
    argv = [command, "--backend", "mujoco", "--turbulence", "strong", "--map", "C"]
    assert _exit_code(argv) == 2
    line = _one_line(capsys.readouterr().err)
    assert "--turbulence" in line and "'strong'" in line and "'moderate'" in line, line


def test_fly_passes_the_turbulence_to_the_env(monkeypatch, capsys):
    import cpp_mujoco.cli.fly as fly_command

    seen = {}

    def fake_fly_mission(policy, grid_map, **kwargs):
        seen.update(kwargs)
        raise ValueError("stopped before flying")

    monkeypatch.setattr(fly_command, "fly_mission", fake_fly_mission)
    argv = ["fly", "--map", "C", "--planner", "safe-greedy", "--turbulence", "severe"]
    assert main(argv) == 2 and "stopped before flying" in capsys.readouterr().err
    assert seen["turbulence"] == "severe" and seen["backend"] == "mujoco"
    assert main([*argv[:-2]]) == 2 and seen["turbulence"] == "none"  # the default: calm


@pytest.mark.parametrize("command", ["evaluate", "fly"])
def test_weather_on_the_grid_backend_is_refused_not_ignored(command, tmp_path, capsys):
    """The grid has no wind: a weather option there would be silently ignored, so it is an error."""
    extra = ["--planner", "safe-greedy"] if command == "fly" else ["--out", str(tmp_path / "o")]
    code = main([command, "--map", "C", "--backend", "grid", "--wind-speed", "5", *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert "--wind-speed" in err and "--backend mujoco" in err
    assert not (tmp_path / "o").exists()


def test_a_folder_given_as_map_or_a_missing_device_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "adir").mkdir()
    assert main(["fly", "--map", "adir", "--planner", "safe-greedy"]) == 2
    assert "'adir' is a folder" in capsys.readouterr().err
    code = main(["train", "--map", "C", "--out", str(tmp_path / "run"), "--set", "device=bogus"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "is not valid; use cpu, cuda" in err
    assert not (tmp_path / "run").exists()  # refused before the run folder is touched


def test_a_rejected_option_with_a_map_object_is_a_short_message():
    """gymnasium's error repeats the kwargs: a GridMap's repr must not bury it in arrays."""
    import gymnasium as gym

    with pytest.raises(TypeError) as err:
        gym.make("cpp_mujoco/MuJoCo-v0", map=load_map("C"), wind_sped=1)
    assert "wind_sped" in str(err.value) and len(str(err.value)) < 2000
    assert repr(load_map("C")).startswith("GridMap('C', 16x16, digest ")
