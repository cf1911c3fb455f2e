"""The top of the results page (:mod:`cpp_mujoco.review.report`): one headline table (per map,
policy and backend: landing, coverage and, where the result has it, the optimum and the gap to
it), the first mission's chase video, and a glossary of every column the page shows — what a
newcomer reads before the detail tables, videos and figures below it."""

from __future__ import annotations

import re
from html import escape
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import quote

from cpp_mujoco.review.report_sections import RESULT_COLUMNS, link
from cpp_mujoco.review.results import optimum_summary_cells
from cpp_mujoco.util.tables import backend_name

if TYPE_CHECKING:
    from cpp_mujoco.review.report import Folder

_RATIO = "share of target cells (green on the maps) the camera saw, the mean over the episodes"
_ACTION = "battery energy of one such action, in budget units (a calm move's energy is 1)"
GLOSSARY = {
    "map": "the grid map flown: a bundled map's name (A, B, C) or a user map's label",
    "policy": "what chose the moves: ddqn[A] is the DDQN agent trained on map A (ddqn-wind: "
    "trained in wind); safe-greedy, beam-search and optimal are reference planners; "
    '"+ guard": flown with the return guard, which turns home when the battery runs low',
    "backend": "grid: the paper's grid world, where each action costs one budget unit; "
    "MuJoCo: the same episodes flown by a simulated quadrotor, the budget a battery energy",
    "episodes": "flights evaluated: every landing cell as the start × every budget",
    "episodes per point": "flights behind each wind speed's cell",
    "landing": "landing ratio: " + "the share of episodes that ended landed on a landing cell "
    "(blue) before the budget ran out; the rest crashed",
    "coverage": f"coverage ratio: the {_RATIO}",
    "grid landing": "the landing ratio on the grid",
    "mujoco landing": "the landing ratio flown in MuJoCo, the same episodes",
    "grid coverage": f"the coverage ratio on the grid: the {_RATIO}",
    "mujoco coverage": "the coverage ratio flown in MuJoCo, the same episodes",
    "optimal": "the best coverage any policy can reach in the same episodes, found by the exact "
    'planner; "bound": not every episode was proven, so the proven upper bound follows; '
    '"[n ep.]": only n episodes are solved',
    "gap to optimal": "the optimal coverage minus the policy's, in percentage points (pt); 0 is "
    "the best possible",
    "paper landing": "the landing ratio Theile et al. (IROS 2020) report for this map's agent",
    "seconds": "the evaluation's wall time",
    "J/action": "MuJoCo: the mean battery energy one action took, in joules",
    "nfz viol.": "no-fly violations: how often the flying quadrotor entered a no-fly cell (red); "
    "anything above 0 is a failure",
    "crashes": "MuJoCo episodes that ended in a crash (battery empty or cut off, a fall, a "
    "collision) instead of a landing",
    "max off-track m": "the largest distance the quadrotor drifted from its cell-to-cell path, "
    "in metres",
    "wind m/s": "the steady wind's speed",
    "from": "the compass direction the wind blows from",
    "weather": "the wind and turbulence flown in",
    "safe greedy": "the safe greedy planner's coverage ratio, the same episodes",
    "beam search": "the beam-search planner's coverage ratio, the same episodes",
    "bar met": "yes when the agent lands at least as often as the paper's and covers at least "
    "as much as the safe greedy planner",
    "file": "the result's JSON file, with every number unrounded",
    "conditions": "what produced the numbers besides map and policy: budgets, wind, "
    "turbulence, seed",
    "conditions (this row)": "the row's conditions that differ from those all rows share",
    **{kind: f"{_ACTION}, {kind}" for kind in ("upwind", "downwind", "crosswind")},
    "hover": f"{_ACTION}: hovering in place",
    "land": f"{_ACTION}: the landing",
}
_SPEED = re.compile(r"[\d.]+ m/s")
_WHERE = {"grid": "on the grid", "mujoco": "flown in MuJoCo"}
SUMMARY_COLUMNS = ["map", "policy", "backend", "episodes", "landing", "coverage"]
OPTIMUM_COLUMNS = ["optimal", "gap to optimal"]


def glossary_term(column: str) -> str | None:
    """What ``column`` means, or None for a column the glossary does not know; a wind speed
    (``6 m/s``) or an action in turbulence (``hover (moderate)``) is read by its kind."""
    if column in GLOSSARY:
        return GLOSSARY[column]
    backend, _, measure = column.partition(" ")
    if backend in _WHERE and measure in GLOSSARY:
        return f"{GLOSSARY[measure]} ({_WHERE[backend]})"
    if _SPEED.fullmatch(column):
        return "landing / coverage ratio at this steady wind speed"
    kind, _, turbulence = column.partition(" (")
    if turbulence and kind in GLOSSARY:
        return f"{GLOSSARY[kind]}, in {turbulence.rstrip(')')} turbulence"
    return None


def _cells(r: dict) -> dict:
    """A result file's headline cells: episodes, landing, coverage, and its optimum if it has."""
    episodes = int(r.get("episodes") or 0)
    cells = {
        "episodes": episodes,
        "landing": f"{r['landing_ratio']:.2%}" if "landing_ratio" in r else "-",
        "coverage": f"{r['coverage_ratio']:.2%}" if "coverage_ratio" in r else "-",
    }
    return {**cells, **(optimum_summary_cells(r["optimum"], episodes) if r.get("optimum") else {})}


def _headline(found: Folder) -> tuple[list[str], list[dict]]:
    """(columns, rows): one row per map and policy, each backend's cells side by side (``grid
    landing``, ``mujoco landing``; one backend: ``landing``); a map and policy with two results
    on one backend: one row per result file; no result file: the folder's first table."""
    if not found.results:
        for tables in found.tables.values():
            for table in tables.values():
                rows = table["rows"]
                extra = [c for c in ("map", "policy") if c not in table["columns"]]
                extra = [c for c in extra if any(c in r for r in rows)]
                return [*extra, *table["columns"]], rows
        return [], []
    results = list(found.results.values())
    backends = sorted(dict.fromkeys(str(r.get("backend", "")) for r in results), key="grid".__ne__)
    keys = [tuple(str(r.get(k, "")) for k in ("map", "policy", "backend")) for r in results]
    policies = {key[1]: i for i, key in reversed(list(enumerate(keys)))}  # first seen first
    solved = {str(r.get("backend", "")) for r in results if r.get("optimum")}
    measures = ["episodes", "landing", "coverage"]
    if len(set(keys)) < len(keys):
        rows = [{"map": k[0], "policy": k[1], "backend": backend_name(k[2]), **_cells(r)}
                for k, r in zip(keys, results, strict=True)]  # fmt: skip
        rows.sort(key=lambda r: (r["map"], policies[r["policy"]], r["backend"] != "grid"))
        return SUMMARY_COLUMNS + (OPTIMUM_COLUMNS if solved else []), rows
    prefix = {b: "" if len(backends) == 1 else f"{b} " for b in backends}
    by_row: dict[tuple, dict] = {}
    for (map_name, policy, backend), r in zip(keys, results, strict=True):
        row = by_row.setdefault((map_name, policy), {"map": map_name, "policy": policy})
        row.update({prefix[backend] + k: v for k, v in _cells(r).items()})
        row["backend"] = backend_name(backend)  # shown when there is one
    columns = ["map", "policy", *(["backend"] if len(backends) == 1 else [])] + [
        prefix[b] + c for b in backends for c in measures + (OPTIMUM_COLUMNS if b in solved else [])
    ]
    return columns, [by_row[k] for k in sorted(by_row, key=lambda k: (k[0], policies[k[1]]))]


def _table(columns: list[str], rows: list[dict]) -> str:
    cells = "".join(
        "<tr>" + "".join(f"<td>{escape(str(r.get(c, '-')))}</td>" for c in columns) + "</tr>"
        for r in rows
    )
    head = "".join(f"<th>{escape(c)}</th>" for c in columns)
    return (
        f'<div class="scroll"><table id="headline"><thead><tr>{head}</tr></thead>'
        f"<tbody>{cells}</tbody></table></div>"
    )


def first_video(found: Folder) -> str | None:
    """The first mission's chase video (its ``video`` file), else the first chase video in the
    folder, else None."""
    for m in found.missions.values():
        files = m.get("files") or {}
        names = [Path(files["video"]).name] if "video" in files else []
        names += [Path(p).name for p in files.values() if str(p).endswith(".mp4")]
        names = [n for n in names if n in found.videos]
        if names:
            return names[0]
    return next((n for n in found.videos if "chase" in n), None)


def page_columns(found: Folder, headline: list[str]) -> list[str]:
    """Every column the page's tables show, the headline's first."""
    columns = list(headline)
    for tables in found.tables.values():
        for table in tables.values():
            rows = table["rows"]
            columns += [c for c in ("map", "policy", "backend") if any(c in r for r in rows)]
            columns += table["columns"]
            if any(r.get("conditions") for r in rows):
                columns.append("conditions (this row)")
    if found.results:
        columns += RESULT_COLUMNS
    return list(dict.fromkeys(columns))


def glossary_html(first: list[str], rest: list[str]) -> str:
    """What each column means: the headline's (``first``) open, the other tables' (``rest``)
    folded under them."""

    def terms(columns: list[str]) -> str:
        entries = [(c, glossary_term(c)) for c in columns]
        items = "".join(
            f"<div><dt>{escape(c)}</dt><dd>{escape(t)}</dd></div>" for c, t in entries if t
        )
        return f"<dl>{items}</dl>" if items else ""

    more = terms([c for c in rest if c not in first])
    if more:
        more = f"<details><summary>the other columns of the tables below</summary>{more}</details>"
    body = terms(first) + more
    return f'<div id="glossary"><h3>What the columns mean</h3>{body}</div>' if body else ""


def summary_html(found: Folder, details: list[tuple[str, str]]) -> str:
    """The summary: the headline table, one video, the glossary, and links to ``details``
    ((anchor, heading) of the sections below)."""
    columns, rows = _headline(found)
    out = [
        "<p>The task: a drone covers the target cells of a grid map with its camera and must "
        "land on a landing cell before its movement budget runs out. Each result is one policy "
        "flown through the protocol: every landing cell as the start, every budget.</p>"
    ]
    if rows:
        about = (
            "per map and policy: the share of episodes landed and of target cells seen"
            if found.results
            else "the folder's first table; all of them are below"
        )
        out.append(f'<p class="about">{escape(about)}</p>{_table(columns, rows)}')
    video = first_video(found)
    if video:
        out.append(
            f'<figure id="first-video"><video controls muted playsinline preload="metadata" '
            f'src="{escape(quote(video))}"></video><figcaption>{link(video)}: the first '
            "mission, seen from the chase camera (every video is below)</figcaption></figure>"
        )
    out.append(glossary_html(columns, page_columns(found, columns)))
    if details:
        links = " · ".join(f'<a href="#{a}">{escape(h)}</a>' for a, h in details)
        out.append(f"<p>Details below: {links}</p>")
    return "".join(out)
