"""One page per output folder: ``index.html`` with its tables, figures, videos and recordings.

Why: a results folder is a pile of JSON, PNG, MP4 and RRD files; a reviewer — on a laptop or a
phone — wants them on one page, each with what produced it: the command that wrote the folder,
and every result's map, policy, backend and conditions (read from the tables' and results' own
JSON, which carry them). The page is built only from what is in the folder, links it with
relative links and loads nothing from the network (inline CSS, no script), so the folder can be
copied, zipped or served as it is. It is written atomically, like every other result file.

The page opens with a summary for a reader new to the project (:mod:`.report_summary`: the
headline table, the first mission's video, what each column means), then the details
(:mod:`.report_sections`: every table, the missions' videos and recordings, the figures).

    write_report("out/demo", command="cpp-mujoco demo")   # → out/demo/index.html
"""

from __future__ import annotations

import json
import os
import shlex
import sys
import time
from dataclasses import dataclass, field
from html import escape
from pathlib import Path

from cpp_mujoco import __version__
from cpp_mujoco.review.report_sections import (
    figures_html,
    link,
    missions_html,
    results_html,
    tables_html,
)
from cpp_mujoco.review.report_summary import summary_html
from cpp_mujoco.util.io import atomic_write_text

REPORT_NAME = "index.html"
_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;line-height:1.45;
 max-width:72rem;margin:0 auto;padding:.75rem;color:#1b1b1b;background:#fff}
h1{font-size:1.5rem}h2{font-size:1.25rem;margin-top:2rem;border-bottom:1px solid #ddd}
h3{font-size:1.05rem}img,video{max-width:100%;height:auto;display:block}
video{background:#000;width:100%}
pre{overflow-x:auto;background:#f4f4f4;padding:.5rem;border-radius:4px;white-space:pre}
.scroll{overflow-x:auto;-webkit-overflow-scrolling:touch}
table{border-collapse:collapse;font-size:.85rem;margin:.5rem 0}
th,td{border:1px solid #ccc;padding:.2rem .45rem;text-align:left;vertical-align:top}
th{background:#f0f0f0}td{white-space:nowrap}td.cond{white-space:normal;min-width:12rem}
.grid{display:grid;grid-template-columns:repeat(auto-fit,minmax(min(100%,22rem),1fr));gap:1rem}
figure{margin:0}figcaption,.about{font-size:.85rem;color:#444}
.cmd{font-family:ui-monospace,monospace}
dl{font-size:.9rem;margin:.25rem 0}dl>div{break-inside:avoid;padding:.15rem 0}dt{font-weight:600}
dd{margin:0 0 0 1.25rem;color:#333}@media(min-width:48rem){dl{columns:2;column-gap:2rem}}
"""


def invocation(argv: list[str] | None = None) -> str:
    """The command line this process was started with, as a reader would type it again
    (``cpp-mujoco demo --out x``, ``python -m cpp_mujoco demo``, ``python scripts/x.py``)."""
    argv = list(sys.argv if argv is None else argv)
    program = Path(argv[0]) if argv else Path("python")
    if program.name == "__main__.py":
        head = ["python", "-m", program.parent.name]
    elif program.suffix == ".py":
        head = ["python", _shown_path(program)]
    else:
        head = [program.name]
    return shlex.join([*head, *argv[1:]])


def script_command(script: str | os.PathLike, argv: list[str] | None) -> str:
    """``python scripts/x.py ARGS`` for a script's ``main(argv)`` (None: the process's own)."""
    args = sys.argv[1:] if argv is None else list(argv)
    return shlex.join(["python", _shown_path(Path(script)), *args])


def _shown_path(path: Path) -> str:
    """A path relative to the working folder where it lies under it, else as given."""
    try:
        return str(path.resolve().relative_to(Path.cwd()))
    except ValueError:
        return str(path)


# ------------------------------------------------------------------------------- what is there
@dataclass
class Folder:
    """The folder's files by kind; JSON files are parsed once and sorted by what they hold."""

    path: Path
    tables: dict[str, dict] = field(default_factory=dict)  # file name → {name: table}
    results: dict[str, dict] = field(default_factory=dict)  # EvaluationResult.to_json files
    missions: dict[str, dict] = field(default_factory=dict)  # MissionOutcome files
    figures: list[str] = field(default_factory=list)
    videos: list[str] = field(default_factory=list)
    recordings: list[str] = field(default_factory=list)
    texts: list[str] = field(default_factory=list)  # .md / .txt shown when no JSON twin
    others: list[str] = field(default_factory=list)


def _is_table(value: object) -> bool:
    return isinstance(value, dict) and isinstance(value.get("columns"), list) and "rows" in value


def scan(folder: Path) -> Folder:
    """Sort the files directly in ``folder`` (hidden and temporary files left out)."""
    found = Folder(folder)
    for path in sorted(p for p in folder.iterdir() if p.is_file()):
        name, suffix = path.name, path.suffix.lower()
        if name.startswith(".") or name == REPORT_NAME:
            continue
        if suffix == ".json":
            try:
                data = json.loads(path.read_text())
            except (OSError, ValueError):
                found.others.append(name)
                continue
            if isinstance(data, dict) and data and all(map(_is_table, data.values())):
                found.tables[name] = data
            elif isinstance(data, dict) and {"policy", "backend", "per_budget"} <= data.keys():
                found.results[name] = data
            elif isinstance(data, dict) and {"policy", "backend", "files"} <= data.keys():
                found.missions[name] = data
            else:
                found.others.append(name)
        elif suffix in (".png", ".jpg", ".jpeg", ".svg"):
            found.figures.append(name)
        elif suffix == ".mp4":
            found.videos.append(name)
        elif suffix == ".rrd":
            found.recordings.append(name)
        elif suffix in (".md", ".txt"):
            found.texts.append(name)
        else:
            found.others.append(name)
    stems = {Path(n).stem for n in found.tables}
    found.others += [n for n in found.texts if Path(n).stem in stems]  # the JSON is shown
    found.texts = [n for n in found.texts if Path(n).stem not in stems]
    return found


def build_report(folder: str | os.PathLike, command: str | None, title: str | None = None) -> str:
    """The page's HTML for ``folder`` as it is now."""
    path = Path(folder)
    found = scan(path)
    shown = str(folder)
    title = title or f"{path.resolve().name}: results"
    details = [
        ("tables", "Tables", tables_html(found) + results_html(found)),
        ("videos", "Missions: videos and recordings", missions_html(found, shown)),
        ("figures", "Figures", figures_html(found)),
        ("files", "Other files", " · ".join(link(n) for n in found.others)),
    ]
    details = [d for d in details if d[2]]
    summary = summary_html(found, [(a, h) for a, h, _ in details])
    body = f'<h2 id="summary">Summary</h2>{summary}' + "".join(
        f'<h2 id="{a}">{escape(h)}</h2>{s}' for a, h, s in details
    )
    command_html = (
        f'<pre class="cmd">{escape(command)}</pre>'
        if command
        else "<p>(the command that wrote this folder was not recorded)</p>"
    )
    stamp = time.strftime("%Y-%m-%d %H:%M:%S %Z")
    return (
        '<!doctype html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{escape(title)}</title><style>{_CSS}</style></head><body>"
        f"<h1>{escape(title)}</h1><p>Written by this command (cpp_mujoco {escape(__version__)}, "
        f"{escape(stamp)}):</p>{command_html}{body}</body></html>\n"
    )


def write_report(
    folder: str | os.PathLike, command: str | None = None, title: str | None = None
) -> Path:
    """Write ``folder/index.html`` (atomically) from what is in ``folder``; ``command``: the
    command line that wrote the folder, shown at the top so a reader can run it again."""
    return atomic_write_text(Path(folder) / REPORT_NAME, build_report(folder, command, title))
