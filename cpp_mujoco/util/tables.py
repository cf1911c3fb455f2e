"""The one table renderer: the same cells as a plain terminal table or as Markdown.

Every table the project prints or writes goes through :func:`format_table`, so a number shown in
the terminal and the same number in a ``.md`` file are one string, formatted once.
"""

from __future__ import annotations

from collections.abc import Sequence

STYLES = ("plain", "markdown")
BACKEND_NAMES = {"grid": "grid", "mujoco": "MuJoCo"}


def backend_name(backend: str) -> str:
    """How tables, figures and the report name a backend (``grid``, ``MuJoCo``; a comparison
    ``grid vs mujoco`` part by part), so one backend has one name everywhere."""
    return " vs ".join(BACKEND_NAMES.get(b, b) for b in str(backend).split(" vs "))


def format_table(
    rows: Sequence[dict],
    columns: Sequence[str],
    floats: str = "{:.4f}",
    style: str = "plain",
) -> str:
    """``columns`` of ``rows`` (a missing cell is blank; floats formatted with ``floats``).

    ``plain``: left-aligned columns, a header and a rule. ``markdown``: a pipe table.
    """
    if style not in STYLES:
        raise ValueError(f"unknown table style {style!r}; available: {', '.join(STYLES)}")

    def cell(value) -> str:
        if isinstance(value, float):
            return floats.format(value)
        return str(value)

    body = [[cell(row.get(c, "")) for c in columns] for row in rows]
    if style == "markdown":
        lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
        lines += ["| " + " | ".join(r) + " |" for r in body]
        return "\n".join(lines)
    widths = [
        max(len(c), *(len(r[i]) for r in body)) if body else len(c) for i, c in enumerate(columns)
    ]
    lines = ["  ".join(c.ljust(w) for c, w in zip(columns, widths, strict=True))]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)) for r in body]
    return "\n".join(lines)
