"""The detail sections of the results page (:mod:`cpp_mujoco.review.report`): every table,
the result files, the figures with the results they show, and each mission's videos and
recording, with what produced each."""

from __future__ import annotations

import json
import re
import shlex
from html import escape
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import quote

from cpp_mujoco.review.report_conditions import conditions_summary, merge
from cpp_mujoco.review.results import file_part
from cpp_mujoco.util.tables import backend_name

if TYPE_CHECKING:
    from cpp_mujoco.review.report import Folder

RESULT_COLUMNS = [
    "file", "map", "policy", "backend", "episodes", "landing", "coverage", "conditions"
]  # fmt: skip


def link(name: str, text: str | None = None) -> str:
    return f'<a href="{escape(quote(name))}">{escape(text or name)}</a>'


def about_html(entries: list[dict]) -> str:
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


def tables_html(found: Folder) -> str:
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
                f'<p class="about">{link(file)} · table <code>{escape(name)}</code> · all rows: '
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
        out.append(f"<h3>{link(name)}</h3><pre>{escape(text)}</pre>")
    return "".join(out)


def results_html(found: Folder) -> str:
    if not found.results:
        return ""
    head = RESULT_COLUMNS
    rows = []
    for file, r in found.results.items():
        cells = [
            link(file),
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


def figures_html(found: Folder) -> str:
    items = []
    for name in found.figures:
        about = about_html(_figure_entries(Path(name).stem, found))
        items.append(
            f'<figure><a href="{escape(quote(name))}"><img src="{escape(quote(name))}" '
            f'alt="{escape(name)}"></a><figcaption>{link(name)}'
            f"{'<br>' + about if about else ''}</figcaption></figure>"
        )
    return f'<div class="grid">{"".join(items)}</div>' if items else ""


def _recording_html(name: str, shown: str) -> str:
    here = shlex.join(["rerun", name])
    there = shlex.join(["rerun", f"{shown.rstrip('/')}/{name}"]) if shown else here
    return (
        f"<p>Recording {link(name)} — open it with Rerun (<code>pip install rerun-sdk==0.41.0"
        f'</code>):</p><pre class="cmd">{escape(there)}</pre>'
        + (f'<p class="about">or, in this folder: <code>{escape(here)}</code></p>' if shown else "")
    )


def missions_html(found: Folder, shown: str) -> str:
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
            f'</h3><p class="about">{about_html([about])} · {m.get("steps")} actions, '
            f"{escape(outcome)}, coverage {m.get('coverage_ratio', 0):.0%} · {link(file)}</p>"
            + media_html([n for n in names if n.endswith(".mp4")])
            + "".join(_recording_html(n, shown) for n in names if n.endswith(".rrd"))
        )
    videos = [n for n in found.videos if n not in claimed]
    recordings = [n for n in found.recordings if n not in claimed]
    if videos or recordings:
        out.append(
            "<h3>Other videos and recordings</h3>"
            + media_html(videos)
            + "".join(_recording_html(n, shown) for n in recordings)
        )
    return "".join(out)


def media_html(videos: list[str]) -> str:
    items = [
        f'<figure><video controls muted playsinline preload="metadata" '
        f'src="{escape(quote(n))}"></video><figcaption>{link(n)}</figcaption></figure>'
        for n in videos
    ]
    return f'<div class="grid">{"".join(items)}</div>' if items else ""
