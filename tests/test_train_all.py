"""``scripts/train_all.py`` stops at the first map whose ``train`` fails: it must never evaluate,
summarise or install a ``best.pt`` left in a folder the training refused."""

import importlib.util
import json
import shutil
from pathlib import Path

import pytest

from cpp_mujoco.agent import BUNDLED_DIR, GENERAL_AGENTS, bundled_agents, load_agent
from cpp_mujoco.agent.config import TrainConfig

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "train_all.py"
WIND_AGENTS = [n for n in bundled_agents() if n.endswith("-wind") and n not in GENERAL_AGENTS]


def _train_all():
    spec = importlib.util.spec_from_file_location("train_all", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_refused_run_folder_stops_the_script(tmp_path, capsys):
    """A folder with an old agent but no checkpoint.pt is refused by ``train``; before the fix
    the script went on to evaluate that stale best.pt and wrote it into summary.json."""
    (tmp_path / "A").mkdir()
    shutil.copyfile(BUNDLED_DIR / "A.pt", tmp_path / "A" / "best.pt")
    code = _train_all().main(["--out", str(tmp_path), "--maps", "A", "B", "--minutes", "0.01"])
    err = capsys.readouterr().err
    assert code == 2
    assert "is not empty" in err  # train's own one-line error
    assert "train_all: training map A failed (exit 2" in err and "run again" in err
    assert not (tmp_path / "summary.json").exists()
    assert not (tmp_path / "B").exists()  # the maps after it did not run


def test_bad_train_option_stops_the_script(tmp_path, capsys):
    code = _train_all().main(["--out", str(tmp_path), "--maps", "A", "--", "--set", "gamma=nan"])
    err = capsys.readouterr().err
    assert code == 2 and "--set gamma" in err and "train_all: training map A failed" in err
    assert list(tmp_path.iterdir()) == []


def test_run_without_an_evaluation_stops_with_a_message(tmp_path, capsys):
    """Too short a run selects no best.pt; the script says so instead of a traceback."""
    fast = [
        "--eval-every",
        "1000000",
        "--set",
        "demo_fraction=0",
        "--set",
        "final_eval=false",
        "--threads",
        "1",
    ]
    argv = ["--out", str(tmp_path), "--maps", "A", "--minutes", "0.002", "--", *fast]
    code = _train_all().main(argv)
    err = capsys.readouterr().err
    assert code == 1 and "best.pt is missing" in err and "--minutes" in err
    assert (tmp_path / "A" / "checkpoint.pt").is_file()  # the run itself is resumable
    assert not (tmp_path / "summary.json").exists()


def test_wind_agents_train_on_the_grid_then_in_physics(tmp_path, monkeypatch):
    """B: two grid runs, the second from the first, then the fine-tune in MuJoCo from the second's
    best.pt; its agent.pt is what --install writes. C: the same three runs, its own options."""
    module = _train_all()
    calls = []

    def fake_train(cmd):  # stands in for `cpp-mujoco train`: records and leaves a finished run
        calls.append(cmd)
        out = Path(cmd[cmd.index("--out") + 1])
        out.mkdir(parents=True, exist_ok=True)
        for name in ("checkpoint.pt", "final_eval.json"):
            (out / name).write_text("")
        trained_on = cmd[cmd.index("--map") + 1]  # an agent of the run's own map
        for name in ("best.pt", "agent.pt"):
            shutil.copyfile(BUNDLED_DIR / f"{trained_on}-wind.pt", out / name)
        return 0

    monkeypatch.setattr(module, "_train", fake_train)
    # what is under test is which runs start from what; the summary's evaluation of the kept
    # agent still runs, on the least and most budget instead of the whole range
    evaluate = module.evaluate
    monkeypatch.setattr(module, "evaluate", lambda agent, m: evaluate(agent, m, budgets=[25, 75]))
    assert module.main(["--wind", "--out", str(tmp_path), "--maps", "B"]) == 0
    first, second, physics = calls

    def opt(cmd, name):
        if name.startswith("--"):
            return cmd[cmd.index(name) + 1]
        return next(s.split("=", 1)[1] for s in cmd if s.startswith(f"{name}="))  # --set

    assert opt(first, "--out") == str(tmp_path / "B-stage1")
    assert opt(first, "--init-from") == "B"  # the paper agent
    assert opt(second, "--out") == str(tmp_path / "B")
    assert opt(second, "--init-from") == str(tmp_path / "B-stage1" / "agent.pt")
    assert [opt(c, "--seed") for c in calls] == ["0", "1", "0"]
    assert opt(second, "best_by") == "landing"
    assert opt(physics, "--out") == str(tmp_path / "B-physics")
    assert opt(physics, "--backend") == "mujoco"
    assert opt(physics, "--init-from") == str(tmp_path / "B" / "best.pt")
    assert opt(physics, "--total-updates") == "3000"
    # B's teachers keep the wider margin from stage 2 on, and physics flies more calm slots
    assert not any(s.startswith("wind_planner_sigmas=") for s in first)
    assert opt(second, "wind_planner_sigmas") == opt(physics, "wind_planner_sigmas") == "6.0"
    assert opt(physics, "physics_calm_share") == "0.5"
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["B"]["agent"] == str(tmp_path / "B-physics" / "agent.pt")
    assert summary["B"]["landing_ratio"] > 0.9  # the agent.pt it kept was evaluated
    calls.clear()  # run again: the finished runs are kept, the last one is resumed
    assert module.main(["--wind", "--out", str(tmp_path), "--maps", "B"]) == 0
    assert len(calls) == 1 and "--resume" in calls[0] and str(tmp_path / "B-physics") in calls[0]
    calls.clear()
    assert module.main(["--wind", "--out", str(tmp_path / "c"), "--maps", "C"]) == 0
    outs = [str(tmp_path / "c" / n) for n in ("C-stage1", "C", "C-physics")]
    assert [opt(c, "--out") for c in calls] == outs
    assert opt(calls[1], "wind_planner_sigmas") == "4.0"  # the planners' own margin
    assert opt(calls[2], "--total-updates") == "2000"


@pytest.mark.parametrize("name", WIND_AGENTS)
def test_each_bundled_wind_agent_is_what_train_all_makes(name):
    """The docs say ``train_all.py --wind`` makes the bundled wind agents: each one's stored
    config holds the options of its map's last wind run (seed included); a hand-copied or
    differently trained file fails here instead of silently standing for the command."""
    m = name.removesuffix("-wind")
    folder, offset, options = _train_all().wind_runs(m, Path("runs/wind"))[-1]
    config = TrainConfig.from_dict(load_agent(name).metadata["config"])
    assert config.map == m and config.seed == offset
    pairs = dict(zip(options[::2], options[1::2], strict=True))
    settings = [v for f, v in zip(options[::2], options[1::2], strict=True) if f == "--set"]
    pairs.pop("--init-from")  # a path on the machine that trained it
    pairs.pop("--set", None)
    given = {flag[2:].replace("-", "_"): value for flag, value in pairs.items()}
    given.update(s.split("=", 1) for s in settings)
    for key, value in given.items():
        have = getattr(config, key)
        want = value == "true" if isinstance(have, bool) else type(have)(value)
        assert want == have, f"{name}: {key}={value} in train_all, {have} bundled"
