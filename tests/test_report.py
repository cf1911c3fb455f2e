"""The results page: built from what is in the folder, relative links only, no network, and —
opened in headless Chromium at a phone's size — its figures load, its videos load their
metadata, its tables show, and nothing is wider than the screen."""

import json
import os
import re
import shutil
import subprocess
import warnings
from html import unescape
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from cpp_mujoco.maps import GridMap
from cpp_mujoco.planners import SafeGreedyPlanner
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.review.report import REPORT_NAME, invocation, script_command, write_report
from cpp_mujoco.review.results import TRANSFER_COLUMNS, Table, write_tables

SMALL = GridMap.from_ascii(["LL.TT", "LL.TT", "....."], name="small")
COMMAND = "cpp-mujoco demo --map small --out out/small"
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome")
PHONE = (390, 844)  # CSS pixels of a common phone screen


def _transfer_table() -> Table:
    table = Table("grid vs MuJoCo, the same episodes", TRANSFER_COLUMNS)
    shared = {"budgets": {"min": 25, "max": 75, "step": 5}}
    table.rows.append({
        "map": "A", "policy": "ddqn[A]", "episodes": 408, "grid landing": "100.00%",
        "mujoco landing": "98.53%", "grid coverage": "87.06%", "mujoco coverage": "87.11%",
        "J/action": "486", "nfz viol.": 0, "backend": "grid vs mujoco", "values": {},
        "conditions": {
            "grid": {"backend": "grid", **shared},
            "mujoco": {"backend": "mujoco", **shared,
                       "physics_config": {"wind_speed": 6.0, "wind_direction": 90.0,
                                          "turbulence": "moderate"}},
        },
    })  # fmt: skip
    return table


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """A small output folder: a table JSON and its Markdown, a result JSON and its figure, a
    mission's MP4 and recording with the mission's JSON, and a file of another kind."""
    import rerun as rr

    from cpp_mujoco.physics.view.rendering import VideoWriter
    from cpp_mujoco.review.plots import trajectories_figure

    out = tmp_path_factory.mktemp("report")
    write_tables(out / "tables.json", {"transfer": _transfer_table()})
    (out / "tables.md").write_text("| map |\n|---|\n| A |\n")
    result = evaluate(SafeGreedyPlanner(), SMALL, budgets=[5, 9], policy_name="safe-greedy")
    result.to_json(out / "grid_small_safe-greedy.json")
    trajectories_figure(result, out / "grid_small_safe-greedy_trajectories.png")
    video = VideoWriter(out / "mission_small_chase.mp4", fps=10)
    for i in range(10):
        video.write(np.full((64, 96, 3), 20 * i, dtype=np.uint8))
    video.close()
    rec = rr.RecordingStream("cpp_mujoco_test")
    rec.save(str(out / "mission_small.rrd"))
    rec.log("metrics/x", rr.Scalars(1.0))
    rec.flush()
    rec.disconnect()
    mission = {
        "map": "small", "policy": "safe-greedy", "backend": "mujoco", "start": [0, 0],
        "budget": 9, "steps": 7, "landed": True, "coverage_ratio": 0.5,
        "conditions": {"seed": 0, "wind_speed": 3.0},
        "files": {"rrd": f"{out}/mission_small.rrd", "video": f"{out}/mission_small_chase.mp4"},
    }  # fmt: skip
    (out / "mission_small.json").write_text(json.dumps(mission))
    (out / "notes.csv").write_text("a,b\n")
    write_report(out, COMMAND)
    return out


class _Page(HTMLParser):
    """Every element's tag and attributes, and the page's text."""

    def __init__(self) -> None:
        super().__init__()
        self.elements: list[tuple[str, dict]] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs) -> None:
        self.elements.append((tag, dict(attrs)))

    def handle_data(self, data) -> None:
        self.text.append(data)


def _parse(html: str) -> _Page:
    page = _Page()
    page.feed(html)
    return page


def test_every_link_is_relative_and_points_to_a_file_in_the_folder(folder):
    html = (folder / REPORT_NAME).read_text()
    page = _parse(html)
    links = [a.get("href") or a.get("src") for _, a in page.elements if "href" in a or "src" in a]
    assert len(links) >= 8
    ids = {a["id"] for _, a in page.elements if "id" in a}
    for link in links:
        assert "://" not in link and not link.startswith(("/", "//")), link
        if link.startswith("#"):
            assert link[1:] in ids, link  # a section of this page
            continue
        assert (folder / link).is_file(), link
    assert "http://" not in html and "https://" not in html  # nothing from the network
    assert '<meta name="viewport"' in html and "max-width:100%" in html
    assert not [p for p in folder.iterdir() if p.name.startswith(".")]  # written atomically


def test_the_page_carries_the_command_and_each_result_with_what_produced_it(folder):
    text = " ".join(_parse((folder / REPORT_NAME).read_text()).text)
    assert COMMAND in text
    assert "rerun mission_small.rrd" in text and f"rerun {folder}/mission_small.rrd" in text
    # the transfer row: map, policy, both backends, and the conditions of each
    assert "ddqn[A]" in text and "grid vs MuJoCo" in text
    assert "MuJoCo: budgets 25..75 step 5, 6 m/s E + moderate turbulence" in text
    # the figure's caption: the result it shows
    assert "map small · policy safe-greedy · backend grid · budgets 5..9 step 4" in text
    # the mission: its policy, backend and conditions beside its video and recording
    assert "policy safe-greedy · backend MuJoCo · 3 m/s, seed 0" in text
    assert "notes.csv" in text  # other files are linked
    assert "| map |" not in text  # the Markdown twin of a shown JSON is only linked


def test_the_command_lines_are_the_ones_to_type_again(tmp_path, monkeypatch):
    assert invocation(["/venv/bin/cpp-mujoco", "demo", "--out", "a b"]) == (
        "cpp-mujoco demo --out 'a b'"
    )
    assert invocation(["/x/cpp_mujoco/__main__.py", "demo"]) == "python -m cpp_mujoco demo"
    monkeypatch.chdir(tmp_path)
    script = tmp_path / "scripts" / "transfer.py"
    assert script_command(script, ["--maps", "B"]) == "python scripts/transfer.py --maps B"


def _browser() -> str | None:
    found = [shutil.which(b) for b in (os.environ.get("CHROMIUM", ""), *BROWSERS) if b]
    return next((b for b in found if b), None)


_CHECK = """<script>
(function () {
  function top(e) { return e ? e.getBoundingClientRect().top + window.scrollY : null; }
  function report() {
    var status = document.createElement("pre");
    status.id = "check-status";
    status.textContent = JSON.stringify({
      images: [].map.call(document.images, function (i) {
        return {src: i.getAttribute("src"), width: i.naturalWidth}; }),
      videos: [].map.call(document.querySelectorAll("video"), function (v) {
        return {src: v.getAttribute("src"), ready: v.readyState,
                error: v.error ? v.error.code : null,
                h264: v.canPlayType('video/mp4; codecs="avc1.42E01E"')}; }),
      scrollWidth: document.documentElement.scrollWidth, innerWidth: window.innerWidth,
      firstVideoTop: top(document.querySelector("video")),
      firstImageTop: top(document.querySelector("img")),
      headlineTop: top(document.getElementById("headline")),
      tablesTop: top(document.getElementById("tables"))
    });
    document.body.appendChild(status);
  }
  var start = Date.now();
  function wait() {
    var videos = [].every.call(document.querySelectorAll("video"), function (v) {
      return v.readyState >= 1 || v.error; });
    var images = [].every.call(document.images, function (i) { return i.complete; });
    if ((videos && images) || Date.now() - start > 8000) { report(); }
    else { setTimeout(wait, 50); }
  }
  window.addEventListener("load", wait);
})();
</script>"""


def test_chromium_renders_the_page_with_its_figures_videos_and_tables(folder, tmp_path):
    browser = _browser()
    if browser is None:
        pytest.skip("no Chromium/Chrome on PATH (scripts/setup.sh installs Debian's chromium)")
    html = (folder / REPORT_NAME).read_text()
    check = folder / "check.html"  # beside the page, so its relative links resolve the same
    check.write_text(html.replace("</body>", _CHECK + "</body>"))
    try:
        run = subprocess.run(
            [browser, "--headless=new", "--disable-gpu", "--no-sandbox", "--no-first-run",
             "--disable-dev-shm-usage", f"--user-data-dir={tmp_path / 'profile'}",
             f"--window-size={PHONE[0]},{PHONE[1]}", "--virtual-time-budget=10000",
             "--dump-dom", check.as_uri()],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    finally:
        check.unlink()
    assert run.returncode == 0, run.stderr[-2000:]
    found = re.search(r'<pre id="check-status">(.*?)</pre>', run.stdout, re.S)
    assert found, f"the page did not finish loading: {run.stdout[-2000:]}"
    status = json.loads(unescape(found.group(1)))
    dom = _parse(run.stdout)
    assert status["images"] and all(i["width"] > 0 for i in status["images"]), status
    for video in status["videos"]:
        if video["ready"] >= 1:
            continue
        # a Chromium built without H.264 cannot open the video: then check what the page
        # relies on instead — the file is there and finalised (its index, the moov box)
        assert video["h264"] == "" and video["error"] == 4, video
        assert b"moov" in (folder / video["src"]).read_bytes()
        warnings.warn(f"{browser} cannot play H.264: checked {video['src']}'s index", stacklevel=1)
    # the first mission's chase video twice: in the summary and beside its mission
    assert [v["src"] for v in status["videos"]] == ["mission_small_chase.mp4"] * 2
    # as laid out: the headline table, then the first video, above the tables and thumbnails
    assert status["headlineTop"] < status["firstVideoTop"] < status["tablesTop"], status
    assert status["firstVideoTop"] < status["firstImageTop"], status
    print(f"{browser}: videos {status['videos']}")  # pytest -s shows whether H.264 played
    # the tables as rendered: their headers and a known cell
    headers = [t for t in dom.text if t.strip()]
    assert "grid landing" in headers and "mujoco coverage" in headers and "87.06%" in headers
    assert status["scrollWidth"] <= status["innerWidth"], status  # nothing wider than a phone


def _position(html: str, marker: str) -> int:
    assert marker in html, marker
    return html.index(marker)


def test_the_summary_opens_the_page_before_the_details(folder):
    html = (folder / REPORT_NAME).read_text()
    summary = _position(html, '<h2 id="summary">')
    headline = _position(html, '<table id="headline">')
    glossary = _position(html, '<div id="glossary">')
    tables = _position(html, '<h2 id="tables">')
    assert summary < headline < glossary < tables
    assert html.index("<table") == headline  # no detail table before the headline
    # the headline: one row per result file, with its landing and coverage
    page = _parse(html[headline : html.index("</table>", headline)])
    cells = [t for t in page.text if t.strip()]
    assert cells[:6] == ["map", "policy", "backend", "episodes", "landing", "coverage"]
    assert ["small", "safe-greedy", "grid", "8"] == cells[6:10]  # 4 starts × 2 budgets


def test_the_first_video_is_above_the_thumbnails(folder):
    html = (folder / REPORT_NAME).read_text()
    video = _position(html, "<video")
    assert video < _position(html, '<h2 id="tables">') < _position(html, "<img")
    assert html[video:].startswith('<video controls muted playsinline preload="metadata" '
                                   'src="mission_small_chase.mp4"')  # fmt: skip
    assert _position(html, '<h2 id="videos">') < _position(html, '<h2 id="figures">')


def test_the_glossary_names_every_column_the_page_shows(folder):
    from cpp_mujoco.review import results
    from cpp_mujoco.review.report_summary import glossary_term

    html = (folder / REPORT_NAME).read_text()
    headers = {
        unescape(h) for h in re.findall(r"<th>(.*?)</th>", html)
    }  # the headline's, the transfer table's and the result files'
    glossary = html[_position(html, '<div id="glossary">') : _position(html, '<h2 id="tables">')]
    terms = {unescape(t) for t in re.findall(r"<dt>(.*?)</dt>", glossary)}
    assert {"landing", "coverage", "nfz viol.", "J/action", "mujoco landing"} <= headers
    assert headers <= terms, headers - terms
    opened = glossary.split("<details>")[0]  # the headline's columns unfolded
    assert "<dt>landing</dt>" in opened and "<dt>coverage</dt>" in opened
    assert "<dt>nfz viol.</dt>" not in opened and "<dt>nfz viol.</dt>" in glossary
    # and every column a results table of the project can have
    columns = [c for name in dir(results) if name.endswith("_COLUMNS")
               for c in getattr(results, name)]  # fmt: skip
    assert [c for c in columns if glossary_term(c) is None] == []
    assert glossary_term("6 m/s") and glossary_term("hover (moderate)")


def test_evaluate_writes_its_page(tmp_path, capsys, monkeypatch):
    from cpp_mujoco.cli.main import main

    argv = ["evaluate", "--map", "C", "--planner", "safe-greedy", "--budget-step", "25"]
    argv += ["--out", str(tmp_path)]
    monkeypatch.setattr("sys.argv", ["/venv/bin/cpp-mujoco", *argv])  # as the console script
    assert main(argv) == 0
    assert f"the page: {tmp_path / REPORT_NAME}" in capsys.readouterr().out
    html = (tmp_path / REPORT_NAME).read_text()
    text = " ".join(_parse(html).text)
    assert "evaluate --map C --planner safe-greedy --budget-step 25" in text
    assert _position(html, '<table id="headline">') < _position(html, '<h2 id="figures">')
    assert "grid_C_safe-greedy_trajectories.png" in html and "landing ratio" in text
    assert "<video" not in html  # no mission, no video


def test_the_headline_puts_each_backend_side_by_side_with_the_optimum(folder, tmp_path):
    data = json.loads((folder / "grid_small_safe-greedy.json").read_text())
    optimum = {"coverage_ratio": 0.9, "bound_ratio": 0.9, "gap_to_optimal": 0.05,
               "statuses": {"optimal": 8}, "episodes_known": 8}  # fmt: skip
    (tmp_path / "grid_small_x.json").write_text(json.dumps({**data, "optimum": optimum}))
    mujoco = {**data, "backend": "mujoco", "landing_ratio": 0.5}
    (tmp_path / "mujoco_small_x.json").write_text(json.dumps(mujoco))
    write_report(tmp_path, COMMAND)
    html = (tmp_path / REPORT_NAME).read_text()
    headline = html[_position(html, '<table id="headline">') :]
    rows = [_parse(r).text for r in re.findall(r"<tr>(.*?)</tr>", headline.split("</table>")[0])]
    assert rows == [
        ["map", "policy", "grid episodes", "grid landing", "grid coverage", "grid optimal",
         "grid gap to optimal", "mujoco episodes", "mujoco landing", "mujoco coverage"],
        ["small", "safe-greedy", "8", "100.00%", f"{data['coverage_ratio']:.2%}", "90.00%",
         "5.00 pt", "8", "50.00%", f"{data['coverage_ratio']:.2%}"],
    ]  # fmt: skip
    terms = re.findall(r"<dt>(.*?)</dt>", html)
    assert set(rows[0]) <= set(terms)
