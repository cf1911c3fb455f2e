"""The ``cpp-mujoco`` command: outputs written; bad input answered with a message, no traceback."""

import json

import pytest

from cpp_mujoco.cli.main import build_parser, main


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
    assert main(["maps", "draw", "--map", "B", "--out", str(tmp_path)]) == 0
    assert "B" in capsys.readouterr().out
    assert (tmp_path / "map_B.png").is_file()


def test_bad_input_is_a_message_not_a_traceback(tmp_path, capsys):
    assert main(["evaluate", "--map", "Z", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "unknown map 'Z'" in err and "Traceback" not in err
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"\x89PNG garbage")
    assert main(["maps", "draw", "--map", str(broken), "--out", str(tmp_path)]) == 2
    assert "unreadable" in capsys.readouterr().err
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["maps", "draw", "--map", "A", "--out", str(blocker / "sub")]) == 2
    assert "cannot create output folder" in capsys.readouterr().err


def _subcommands(parser):
    return parser._subparsers._group_actions[0].choices  # noqa: SLF001


def test_every_subcommand_is_registered_the_same_way():
    # before: train set args.handler and kept its own convention beside cli.py's func
    from cpp_mujoco.cli.main import command

    for name, sub in _subcommands(build_parser()).items():
        func = sub.get_default("func")
        assert callable(func) or func.startswith("cpp_mujoco.cli."), name
        assert callable(command(func)), name
        assert sub.get_default("handler") is None, name


def test_help_without_train_options_lists_the_same_commands():
    light, full = build_parser(train_options=False), build_parser()
    assert light.format_help() == full.format_help()
    assert list(_subcommands(light)) == list(_subcommands(full))
    assert full.parse_args(["train", "--out", "x", "--num-envs", "4"]).num_envs == 4


_LIGHT = """
import sys
from cpp_mujoco.cli.main import main
for argv in (["--version"], ["--help"], ["evaluate", "--help"], ["benchmark", "--help"]):
    try:
        main(argv)
    except SystemExit:
        pass
heavy = ("torch", "mujoco", "matplotlib", "cpp_mujoco.agent", "cpp_mujoco.protocol.evaluate")
print("imported:", *sorted(m for m in heavy if m in sys.modules))
"""


def test_help_and_version_import_no_heavy_module():
    # before: building the parser imported cpp_mujoco.agent and torch (4 s for --version)
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _LIGHT], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "imported:", out.stdout[-500:]


def test_every_benchmark_section_is_a_module_with_run():
    import importlib
    import inspect

    from cpp_mujoco.cli.benchmark import SECTIONS

    assert list(SECTIONS) == ["grid", "physics", "training", "review", "decision"]
    for name, module in SECTIONS.items():
        run = importlib.import_module(module).run
        required = [p for p in inspect.signature(run).parameters.values() if p.default is p.empty]
        assert not required, (name, required)


def test_unknown_benchmark_section_is_one_line_before_anything_runs(tmp_path, capsys):
    code = main(["benchmark", "--only", "grid", "gpu", "--json", str(tmp_path / "b.json")])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "'gpu'" in err
    assert "known: grid, physics, training, review, decision" in err
    assert not (tmp_path / "b.json").exists()


# ------------------------------------------------------------------------- the docs' file map
def _layout_rows(path: str, heading: str) -> list[tuple[str, list[str]]]:
    """A layout table: (first path of the row, every backticked name in the row)."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / path).read_text(encoding="utf-8")
    section = text.split(f"{heading}\n", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| `")]
    return [(re.findall(r"`([^`]+)`", r)[0], re.findall(r"`([^`]+)`", r)) for r in rows]


def test_docs_layout_names_every_module_script_and_doc_and_nothing_else():
    # before: the table missed 20 modules (policy.py, episode.py, io.py, grid/single_env.py, ...)
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    listed: set[str] = set()
    for first, names in _layout_rows("docs/layout.md", "# Layout: every file"):
        base = first if first.endswith("/") else str(Path(first).parent) + "/"
        for name in names:
            if name.endswith((".py", ".md", ".sh")) and " " not in name:
                top = name.split("/")[0]
                listed.add(name if top in ("cpp_mujoco", "assets", "scripts") else base + name)
    package = {str(p.relative_to(root)) for p in (root / "cpp_mujoco").rglob("*.py")}
    wanted = {p for p in package if not p.endswith("/__init__.py")}
    wanted |= {f"scripts/{p.name}" for p in (root / "scripts").iterdir() if p.is_file()}
    wanted |= {f"docs/{p.name}" for p in (root / "docs").glob("*.md")}
    wanted |= {f"docs/api/{p.name}" for p in (root / "docs" / "api").glob("*.md")}
    assert sorted(wanted - listed) == [], "missing from docs/layout.md"
    stale = sorted(p for p in listed if not (root / p).is_file())
    assert stale == [], "named in docs/layout.md but not in the tree"


def test_readme_layout_names_every_package_and_top_folder_once():
    """README's Layout is the short map: one row per package of cpp_mujoco and per top folder."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    firsts = [first for first, _ in _layout_rows("README.md", "## Layout")]
    packages = sorted(
        f"cpp_mujoco/{p.name}/"
        for p in (root / "cpp_mujoco").iterdir()
        if (p / "__init__.py").is_file()
    )
    wanted = [*packages, "assets/", "maps/", "scripts/", "docs/", "results/", "tests/"]
    assert [w for w in wanted if firsts.count(w) != 1] == [], "not one README Layout row each"
    assert all((root / first).exists() for first in firsts), "README's Layout names a missing path"


def test_architecture_page_cites_only_files_that_exist():
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    text = (root / "docs" / "architecture.md").read_text(encoding="utf-8")
    packages = "|".join(
        p.name for p in (root / "cpp_mujoco").iterdir() if (p / "__init__.py").is_file()
    )
    folders = rf"(?:scripts/|(?:{packages})/(?:\w+/)?)?"
    cited = set(re.findall(rf"(?<![\w/])({folders}\w+\.py)\b", text))
    assert len(cited) > 30
    missing = [
        c for c in cited
        if not (root / c if c.startswith("scripts/") else root / "cpp_mujoco" / c).is_file()
    ]  # fmt: skip
    assert missing == []


def test_the_architecture_page_draws_the_checked_layers_in_their_order():
    """docs/architecture.md's drawing of the layers is the import-linter contract's order."""
    import re
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    config = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8"))
    (contract,) = [c for c in config["tool"]["importlinter"]["contracts"] if c["type"] == "layers"]
    checked = [
        [name.strip().removeprefix("cpp_mujoco.") for name in layer.split("|")]
        for layer in contract["layers"]
    ]
    text = (root / "docs" / "architecture.md").read_text(encoding="utf-8")
    drawing = text.split("```\n", 2)[1]  # the first code block: the layers, top first
    drawn = [
        [name.strip() for name in m.group(1).split("|")]
        for m in re.finditer(r"^  (\w+(?:  \|  \w+)?)(?:  |$)", drawing, re.M)
    ]
    assert drawn == checked
