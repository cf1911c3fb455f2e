"""The documentation site (mkdocs.yml, docs/): it builds with every warning an error, its pages
hold no diary, and headless Chromium opens the home page and an API page built from docstrings."""

import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome")
# the words of a diary: work periods, dates of work, what a request asked for
DIARY = re.compile(r"\bsessions?\b|\bthe issue\b|\b20\d\d-\d\d-\d\d\b|\bwe tried\b", re.I)


def _browser() -> str | None:
    found = [shutil.which(b) for b in (os.environ.get("CHROMIUM", ""), *BROWSERS) if b]
    return next((b for b in found if b), None)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site, built strictly (a warning fails the build) into a temporary folder."""
    if importlib.util.find_spec("mkdocs") is None:
        pytest.skip('mkdocs is not installed (pip install -e ".[docs]")')
    out = tmp_path_factory.mktemp("site")
    run = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-q",
         "-f", str(ROOT / "mkdocs.yml"), "-d", str(out)],
        capture_output=True, text=True, timeout=300, cwd=ROOT,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    return out


def _dom(browser: str, page: Path, profile: Path) -> str:
    run = subprocess.run(
        [browser, "--headless=new", "--disable-gpu", "--no-sandbox", "--no-first-run",
         "--disable-dev-shm-usage", f"--user-data-dir={profile}", "--virtual-time-budget=5000",
         "--dump-dom", page.as_uri()],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout


def test_the_pages_hold_no_diary():
    """History lives in CHANGELOG.md; the pages say what is, in the present tense (the
    generated results pages, which date their measurements, aside)."""
    pages = [p for p in (ROOT / "docs").rglob("*.md") if "results" not in p.parts]
    hits = [
        f"{p.relative_to(ROOT)}:{n}: {line.strip()[:80]}"
        for p in pages
        for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
        if DIARY.search(line)
    ]
    assert hits == []


def test_every_page_is_in_the_nav_and_every_api_page_renders_a_module(site):
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    pages = [p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md")]
    assert [p for p in pages if p not in nav and not p.startswith("results/")] == []
    for page in (ROOT / "docs" / "api").glob("*.md"):
        if page.name == "index.md":
            continue
        html = (site / "api" / page.stem / "index.html").read_text(encoding="utf-8")
        for module in re.findall(r"^::: (\S+)", page.read_text(encoding="utf-8"), re.M):
            assert f'id="{module}"' in html, (page.name, module)


def test_chromium_opens_the_home_page_and_the_protocol_api_page(site, tmp_path):
    browser = _browser()
    if browser is None:
        pytest.skip("no Chromium/Chrome on PATH (scripts/setup.sh installs Debian's chromium)")
    home = _dom(browser, site / "index.html", tmp_path / "profile")
    assert re.search(r"<title>\s*cpp_mujoco\s*</title>", home), home[:500]
    assert "Where to start" in home and "API reference" in home
    assert 'href="getting-started/"' in home
    api = _dom(browser, site / "api" / "protocol" / "index.html", tmp_path / "profile")
    text = re.sub(r"<[^>]+>", "", api)
    assert "cpp_mujoco.protocol.evaluate" in text
    assert re.search(r"\bevaluate\(\s*policy", text), "evaluate's signature is missing"
    assert "EvaluationResult" in text
