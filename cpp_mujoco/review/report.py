"""One page per output folder: ``index.html`` with its tables, figures, videos and recordings.

Why: a results folder is a pile of JSON, PNG, MP4 and RRD files; a reviewer — on a laptop or a
phone — wants them on one page, each with what produced it: the command that wrote the folder,
and every result's map, policy, backend and conditions (read from the tables' and results' own
JSON, which carry them). The page is built only from what is in the folder, links it with
relative links and loads nothing from the network (inline CSS, no script), so the folder can be
copied, zipped or served as it is. It is written atomically, like every other result file.

    write_report("out/demo", command="cpp-mujoco demo")   # → out/demo/index.html
"""

from __future__ import annotations

import json
import os
import re
import shlex
import sys
import time
from dataclasses import dataclass, field
from html import escape
from pathlib import Path
from urllib.parse import quote

from cpp_mujoco import __version__
from cpp_mujoco.review.report_conditions import conditions_summary, merge
from cpp_mujoco.review.results import file_part
from cpp_mujoco.util.io import atomic_write_text
from cpp_mujoco.util.tables import backend_name

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


# ------------------------------------------------------------------------------------ the page
def _link(name: str, text: str | None = None) -> str:
    return f'<a href="{escape(quote(name))}">{escape(text or name)}</a>'


def _about(entries: list[dict]) -> str:
    """Map, policy, backend and conditions of the results a figure or video shows."""
    if not entries:
        return ""

    def values(key: str, show=str) -> str:
        return ", ".join(dict.fromkeys(show(e[key]) for e in entries if e.get(key) is not None))

    conditions = dict.fromkeys(
        conditions_summary(e.get("conditions") or {}, with_backend=False) for e in entries
    )
    parts = [
        f"map {values('map')}",
        f"policy {values('policy')}",
        f"backend {values('backend', backend_name)}",
        "; ".join(c for c in conditions if c) or "conditions not recorded",
    ]
    return escape(" · ".join(parts))


def _table_entries(table: dict) -> list[dict]:
    """Each row with its full conditions (the table's shared ones under its own)."""
    shared = table.get("conditions") or {}
    return [
        {**row, "conditions": merge(shared, row.get("conditions") or {})} for row in table["rows"]
    ]


def _tables_html(found: Folder) -> str:
    out = []
    for file, tables in found.tables.items():
        for name, table in tables.items():
            columns = list(table["columns"])
            rows = table["rows"]
            extra = [c for c in ("map", "policy") if c not in columns and any(c in r for r in rows)]
            if "backend" not in columns and any("backend" in r for r in rows):
                extra.append("backend")
            shared = table.get("conditions") or {}
            own = any(r.get("conditions") for r in rows)
            head = [*extra, *columns] + (["conditions (this row)"] if own else [])
            body = []
            for row in rows:
                cells = [
                    escape(backend_name(row.get(c, "")) if c == "backend" else str(row.get(c, "")))
                    for c in [*extra, *columns]
                ]
                html_cells = "".join(f"<td>{c}</td>" for c in cells)
                if own:
                    full = merge(shared, row.get("conditions") or {})
                    text = conditions_summary(full, leave_out=shared)
                    html_cells += f'<td class="cond">{escape(text)}</td>'
                body.append(f"<tr>{html_cells}</tr>")
            out.append(
                f'<h3 id="{escape(file)}-{escape(name)}">{escape(table.get("title", name))}</h3>'
                f'<p class="about">{_link(file)} · table <code>{escape(name)}</code> · all rows: '
                f"{escape(conditions_summary(shared) or 'conditions in the rows')}</p>"
                '<div class="scroll"><table><thead><tr>'
                + "".join(f"<th>{escape(h)}</th>" for h in head)
                + "</tr></thead><tbody>"
                + "".join(body)
                + "</tbody></table></div>"
                + (
                    "<details><summary>all shared conditions (JSON)</summary><pre>"
                    f"{escape(json.dumps(shared, indent=1))}</pre></details>"
                    if shared
                    else ""
                )
            )
    for name in found.texts:
        text = (found.path / name).read_text(errors="replace")
        out.append(f"<h3>{_link(name)}</h3><pre>{escape(text)}</pre>")
    return "".join(out)


def _results_html(found: Folder) -> str:
    if not found.results:
        return ""
    head = ["file", "map", "policy", "backend", "episodes", "landing", "coverage", "conditions"]
    rows = []
    for file, r in found.results.items():
        cells = [
            _link(file),
            escape(str(r.get("map", ""))),
            escape(str(r.get("policy", ""))),
            escape(backend_name(r.get("backend", ""))),
            escape(str(r.get("episodes", ""))),
            f"{r['landing_ratio']:.2%}" if "landing_ratio" in r else "",
            f"{r['coverage_ratio']:.2%}" if "coverage_ratio" in r else "",
        ]
        cond = escape(
            conditions_summary({"backend": r.get("backend"), **(r.get("conditions") or {})})
        )
        rows.append("".join(f"<td>{c}</td>" for c in cells) + f'<td class="cond">{cond}</td>')
    return (
        '<h3>Every result file</h3><div class="scroll"><table><thead><tr>'
        + "".join(f"<th>{h}</th>" for h in head)
        + "</tr></thead><tbody>"
        + "".join(f"<tr>{r}</tr>" for r in rows)
        + "</tbody></table></div>"
    )


def _token_in(key: str, stem: str) -> bool:
    return bool(key) and re.search(rf"(^|_){re.escape(key)}(_|$)", stem) is not None


def _figure_entries(stem: str, found: Folder) -> list[dict]:
    """The results a figure shows, first match wins: the result file its name extends
    (``mujoco_A_x_trajectories`` ← ``mujoco_A_x.json``); the rows of the table its name starts
    with, of the map and policy it names (``transfer_A_ddqn_A``: the transfer row of A and
    ``ddqn[A]``); result files named inside its name or by its map (``grid_A_coverage``); the
    table file of the same name (``wind_sweep``); the table rows of the map it names."""

    def result(r: dict) -> dict:
        return {**r, "conditions": {"backend": r.get("backend"), **(r.get("conditions") or {})}}

    def rows(name: str | None = None) -> list[dict]:
        return [
            e
            for tables in found.tables.values()
            for key, t in tables.items()
            if name is None or key == name
            for e in _table_entries(t)
            if "policy" in e
        ]

    def label(e: dict) -> str:
        return f"{file_part(str(e.get('map', '')))}_{file_part(str(e.get('policy', '')))}"

    exact = [r for f, r in found.results.items() if _token_in(Path(f).stem, stem)]
    if exact:
        return [result(r) for r in exact]
    table = stem.split("_", 1)[0]
    named = [e for e in rows(table) if _token_in(label(e), stem)]
    if named:
        return named
    hits = []
    for file, r in found.results.items():
        key = Path(file).stem.removeprefix(f"{r.get('backend')}_")
        by_map = f"{r.get('backend')}_{file_part(str(r.get('map', '')))}_coverage"
        if _token_in(key, stem) or stem == by_map:
            hits.append(result(r))
    if hits:
        return hits
    for file, tables in found.tables.items():
        if Path(file).stem == stem:
            return [e for t in tables.values() for e in _table_entries(t) if "map" in e]
    return [e for e in rows() if _token_in(file_part(str(e.get("map", ""))), stem)]


def _figures_html(found: Folder) -> str:
    items = []
    for name in found.figures:
        about = _about(_figure_entries(Path(name).stem, found))
        items.append(
            f'<figure><a href="{escape(quote(name))}"><img src="{escape(quote(name))}" '
            f'alt="{escape(name)}"></a><figcaption>{_link(name)}'
            f"{'<br>' + about if about else ''}</figcaption></figure>"
        )
    return f'<div class="grid">{"".join(items)}</div>' if items else ""


def _recording_html(name: str, shown: str) -> str:
    here = shlex.join(["rerun", name])
    there = shlex.join(["rerun", f"{shown.rstrip('/')}/{name}"]) if shown else here
    return (
        f"<p>Recording {_link(name)} — open it with Rerun (<code>pip install rerun-sdk==0.41.0"
        f'</code>):</p><pre class="cmd">{escape(there)}</pre>'
        + (f'<p class="about">or, in this folder: <code>{escape(here)}</code></p>' if shown else "")
    )


def _missions_html(found: Folder, shown: str) -> str:
    """Each mission's videos (playing in the page) and recording, with what flew it; files
    that no mission JSON claims follow on their own."""
    out, claimed = [], set()
    for file, m in found.missions.items():
        names = [Path(p).name for p in (m.get("files") or {}).values()]
        names = [n for n in names if (found.path / n).is_file()]
        claimed |= set(names)
        about = {**m, "conditions": {"backend": m.get("backend"), **(m.get("conditions") or {})}}
        outcome = "landed" if m.get("landed") else f"crashed ({m.get('crash_reason')})"
        out.append(
            f"<h3>map {escape(str(m.get('map')))}: {escape(str(m.get('policy')))} from "
            f"{escape(str(tuple(m.get('start') or ())))}, budget {escape(str(m.get('budget')))}"
            f'</h3><p class="about">{_about([about])} · {m.get("steps")} actions, '
            f"{escape(outcome)}, coverage {m.get('coverage_ratio', 0):.0%} · {_link(file)}</p>"
            + _media_html([n for n in names if n.endswith(".mp4")])
            + "".join(_recording_html(n, shown) for n in names if n.endswith(".rrd"))
        )
    videos = [n for n in found.videos if n not in claimed]
    recordings = [n for n in found.recordings if n not in claimed]
    if videos or recordings:
        out.append(
            "<h3>Other videos and recordings</h3>"
            + _media_html(videos)
            + "".join(_recording_html(n, shown) for n in recordings)
        )
    return "".join(out)


def _media_html(videos: list[str]) -> str:
    items = [
        f'<figure><video controls muted playsinline preload="metadata" '
        f'src="{escape(quote(n))}"></video><figcaption>{_link(n)}</figcaption></figure>'
        for n in videos
    ]
    return f'<div class="grid">{"".join(items)}</div>' if items else ""


def build_report(folder: str | os.PathLike, command: str | None, title: str | None = None) -> str:
    """The page's HTML for ``folder`` as it is now."""
    path = Path(folder)
    found = scan(path)
    shown = str(folder)
    title = title or f"{path.resolve().name}: results"
    sections = [
        ("Tables", _tables_html(found) + _results_html(found)),
        ("Figures", _figures_html(found)),
        ("Missions: videos and recordings", _missions_html(found, shown)),
        ("Other files", " · ".join(_link(n) for n in found.others)),
    ]
    body = "".join(f"<h2>{escape(h)}</h2>{s}" for h, s in sections if s)
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
