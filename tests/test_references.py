"""Text in the repository cites only what the repository holds."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TEXT = [ROOT / "README.md", *ROOT.glob("docs/*.md")]
TEXT += [p for d in ("cpp_mujoco", "tests", "scripts") for p in (ROOT / d).rglob("*.py")]


def test_no_citation_of_a_design_document_the_repository_does_not_hold():
    # before: the README, grid/mdp.py and a test cited section 3 of a DESIGN document not here
    cited = "DESIGN" + " §"  # split, so this file does not cite it either
    hits = [str(p.relative_to(ROOT)) for p in TEXT if cited in p.read_text(encoding="utf-8")]
    assert not hits


def test_the_tests_pyproject_cites_exist():
    # before: pyproject.toml cited tests/test_dependencies.py, which does not exist
    text = (ROOT / "pyproject.toml").read_text()
    cited = re.findall(r"(tests/[\w/]+\.py)(?:::(\w+))?", text)
    assert cited
    for path, test in cited:
        assert (ROOT / path).is_file(), path
        if test:
            assert f"def {test}(" in (ROOT / path).read_text(), (path, test)
