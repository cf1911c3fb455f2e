"""Results tables: one module builds them, one renderer shows them, JSON keeps their conditions;
figures leave matplotlib's backend alone."""

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

from cpp_mujoco.maps import GridMap
from cpp_mujoco.missions.lineup import run_evaluation
from cpp_mujoco.planners import SafeGreedyPlanner
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.review.results import (
    PROTOCOL_COLUMNS,
    Table,
    paper_row,
    protocol_row,
    split_conditions,
    transfer_row,
)
from cpp_mujoco.util.tables import format_table

ROOT = Path(__file__).resolve().parents[1]
SMALL = GridMap.from_ascii(["LL.TT", "LL.TT", "....."], name="small")


@pytest.fixture(scope="module")
def results():
    """Two grid results of the same policy on SMALL over different budgets."""
    return [
        evaluate(SafeGreedyPlanner(), SMALL, budgets=[5, 9], policy_name="safe-greedy"),
        evaluate(SafeGreedyPlanner(), SMALL, budgets=[5, 9, 13], policy_name="safe-greedy"),
    ]


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            names |= {f"{node.module}.{a.name}" for a in node.names} | {node.module}
        elif isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
    return names


@pytest.mark.parametrize(
    "path", ["scripts/transfer.py", "scripts/results.py", "cpp_mujoco/missions/demo.py"]
)
def test_tables_come_from_the_results_module_only(path):
    # before: transfer.py imported demo's row builder and kept its own Markdown renderer, and
    # results.py and the demo built their rows by hand
    names = _imports(ROOT / path)
    assert "cpp_mujoco.review.results" in names
    assert not {n for n in names if n.startswith(("cpp_mujoco.missions.demo", "cpp_mujoco.cli"))}
    assert "cpp_mujoco.util.tables.format_table" not in names  # rendered through Table
    assert "matplotlib" not in names and "matplotlib.pyplot" not in names


def test_plain_and_markdown_show_the_same_cells():
    rows = [{"map": "A", "wind m/s": 3.0, "landing": "99.00%"}]
    columns = ["map", "wind m/s", "landing"]
    plain = format_table(rows, columns).splitlines()[2].split()
    markdown = format_table(rows, columns, style="markdown").splitlines()[2]
    assert [c.strip() for c in markdown.strip("|").split("|")] == plain == ["A", "3.0000", "99.00%"]
    with pytest.raises(ValueError, match="unknown table style 'html'"):
        format_table(rows, columns, style="html")


def test_rows_carry_map_policy_backend_and_unrounded_numbers(results):
    row = protocol_row(results[0], seconds=1.234)
    assert (row["map"], row["policy"], row["backend"]) == ("small", "safe-greedy", "grid")
    assert row["map_digest"] == SMALL.digest
    assert row["paper landing"] == "-"  # the paper's figures belong to the bundled maps only
    assert row["values"]["coverage_ratio"] == results[0].coverage_ratio  # not the rounded cell
    assert row["seconds"] == "1.23"


def test_table_json_shares_common_conditions_and_keeps_what_differs(results):
    table = Table("t", PROTOCOL_COLUMNS, [protocol_row(r) for r in results]).to_dict()
    assert table["conditions"]["grid_config"]["fov_side"] == 3  # stated once for all rows
    assert table["conditions"]["env_kwargs"] == {}  # an empty option set is still stated
    assert table["conditions"]["budgets"] == {"min": 5, "step": 4}
    own = [r["conditions"] for r in table["rows"]]
    assert [c["budgets"]["max"] for c in own] == [9, 13]
    assert [c["episodes"] for c in own] == [8, 12]
    assert "grid_config" not in own[0]


def test_split_conditions_recurses_into_what_differs():
    shared, own = split_conditions(
        [
            {"wind": {"speed": 0.0, "gust": 1.0}, "v": 1},
            {"wind": {"speed": 3.0, "gust": 1.0}, "v": 1},
        ]
    )
    assert shared == {"wind": {"gust": 1.0}, "v": 1}
    assert own == [{"wind": {"speed": 0.0}}, {"wind": {"speed": 3.0}}]


def test_comparison_rows_refuse_results_that_do_not_match(results):
    # before: a transfer row of two different maps or budget sets was printed without a word
    other = evaluate(SafeGreedyPlanner(), GridMap.from_ascii(["LT"], name="tiny"), budgets=[5, 9])
    with pytest.raises(ValueError, match="maps 'small' and 'tiny'"):
        transfer_row(results[0], other)
    with pytest.raises(ValueError, match="different budgets"):
        transfer_row(results[0], results[1])
    with pytest.raises(ValueError, match="not bundled"):
        paper_row(results[0], results[0], results[0])


def test_evaluation_writes_the_table_with_its_conditions(tmp_path, capsys, results):
    run_evaluation([SMALL], [("safe-greedy", SafeGreedyPlanner())], tmp_path, budgets=[5, 9])
    printed = capsys.readouterr().out
    data = json.loads((tmp_path / "grid_tables.json").read_text())["protocol"]
    assert data["columns"] == PROTOCOL_COLUMNS
    (row,) = data["rows"]
    assert row["map"] == "small" and row["backend"] == "grid" and row["landing"] in printed
    assert row["values"]["coverage_ratio"] == results[0].coverage_ratio
    assert data["conditions"]["budgets"] == {"min": 5, "max": 9, "step": 4}


_DRAW = """
import sys, matplotlib
matplotlib.use("pdf")
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.maps import GridMap
from cpp_mujoco.planners import SafeGreedyPlanner
from cpp_mujoco.review import plots
out = sys.argv[1]
small = GridMap.from_ascii(["LL.TT", "LL.TT", "....."], name="small")
result = evaluate(SafeGreedyPlanner(), small, budgets=[5, 9])
plots.map_figure(small, out + "/map.png")
plots.trajectories_figure(result, out + "/traj.png")
plots.coverage_figure([result], out + "/coverage.png")
plots.wind_sweep_figure([result], out + "/wind.png")
print("matplotlib.pyplot" in sys.modules, matplotlib.rcParams._get("backend"))
"""


def test_drawing_figures_leaves_the_matplotlib_backend_alone(tmp_path):
    # before: importing review.plots switched the process to Agg and imported pyplot
    env = {k: v for k, v in __import__("os").environ.items() if k != "MPLBACKEND"}
    out = subprocess.run(
        [sys.executable, "-c", _DRAW, str(tmp_path)], capture_output=True, text=True, env=env
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["False", "pdf"]
    for name in ("map", "traj", "coverage", "wind"):
        assert (tmp_path / f"{name}.png").read_bytes()[:4] == b"\x89PNG"
