"""Where the package imports: at the top of a module, but for an optional or heavy dependency kept
off a light path, which says so on its line; and which paths stay light (docs/architecture.md)."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# the reasons a function-level import may give, as its line's comment begins
REASONS = ("# optional:", "# heavy:", "# GL:")
# uncommented function-level imports in the trainer's modules; a count may only fall
UNCOMMENTED: dict[str, int] = {}  # files allowed function-level imports without a reason


def _function_level_imports(path: Path) -> list[ast.Import | ast.ImportFrom]:
    found = []

    def walk(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if in_function and isinstance(child, ast.Import | ast.ImportFrom):
                found.append(child)
            walk(child, in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef))

    walk(ast.parse(path.read_text(encoding="utf-8")), False)
    return found


def _says_why(lines: list[str], node: ast.stmt) -> bool:
    return any(
        reason in line for line in lines[node.lineno - 1 : node.end_lineno] for reason in REASONS
    )


def test_every_function_level_import_says_why():
    # before: 160 imports inside functions, most of them for no reason any longer
    unexplained: dict[str, list[int]] = {}
    for path in sorted((ROOT / "cpp_mujoco").rglob("*.py")):
        lines = path.read_text(encoding="utf-8").splitlines()
        rows = [n.lineno for n in _function_level_imports(path) if not _says_why(lines, n)]
        if rows:
            unexplained[str(path.relative_to(ROOT))] = rows
    over = {
        name: rows for name, rows in unexplained.items() if len(rows) > UNCOMMENTED.get(name, 0)
    }
    assert over == {}, f"function-level imports without a reason ({', '.join(REASONS)})"


def test_the_check_finds_an_import_without_a_reason(tmp_path):
    module = tmp_path / "m.py"
    module.write_text(
        "import os\n\n\ndef f():\n    import json\n    import ray  # optional: the ray extra\n"
        "    from x import (  # heavy: x\n        y,\n    )\n"
    )
    lines = module.read_text().splitlines()
    found = _function_level_imports(module)
    assert [n.lineno for n in found] == [5, 6, 7]
    assert [_says_why(lines, n) for n in found] == [False, True, True]


def _loaded(code: str, names: tuple[str, ...]) -> list[str]:
    """The modules of ``names`` a fresh interpreter has loaded after running ``code``."""
    probe = f"{code}\nimport sys\nprint(*sorted(m for m in {names!r} if m in sys.modules))"
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, cwd=ROOT, check=False
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.split()


HEAVY = ("torch", "mujoco", "matplotlib")


def test_the_command_line_imports_no_heavy_module():
    assert _loaded("import cpp_mujoco.cli.main", HEAVY) == []


@pytest.mark.parametrize(
    "module",
    [
        "cpp_mujoco.grid",
        "cpp_mujoco.maps",
        "cpp_mujoco.map_sets.sets",
        "cpp_mujoco.planners",
        "cpp_mujoco.protocol.evaluate",
        "cpp_mujoco.protocol.map_sets",
        "cpp_mujoco.missions.mission",
    ],
)
def test_the_grid_path_imports_neither_torch_nor_mujoco(module):
    assert _loaded(f"import {module}", ("torch", "mujoco", "dm_control")) == []


def test_commands_that_render_import_no_mujoco_before_choosing_gl():
    # MuJoCo and dm_control bind their GL backend at import: configure_gl must come first
    code = (
        "import cpp_mujoco.cli.fly, cpp_mujoco.cli.demo, cpp_mujoco.missions.stills,"
        " cpp_mujoco.bench.review"
    )
    assert _loaded(code, ("mujoco", "dm_control")) == []
