"""``cpp-mujoco benchmark``: the speed figures, measured on this machine.

One pattern for every section: a module with ``run() -> dict`` (a flat dict of numbers),
registered in :data:`SECTIONS` by module name and imported only when its section runs — so the
command line knows the sections without importing torch or MuJoCo.
"""

from __future__ import annotations

import importlib

from cpp_mujoco.cli.options import add_progress_option, check_output_file, progress_wanted

SECTIONS: dict[str, str] = {
    "grid": "cpp_mujoco.bench.grid",
    "physics": "cpp_mujoco.bench.physics",
    "training": "cpp_mujoco.bench.agent",
    "review": "cpp_mujoco.bench.review",
}


def run_section(name: str) -> dict:
    """Import the section's module and return its ``run()``."""
    if name not in SECTIONS:
        raise ValueError(f"unknown benchmark section {name!r}; known: {', '.join(SECTIONS)}")
    return importlib.import_module(SECTIONS[name]).run()


def run_sections(names: list[str], progress: bool = False) -> dict[str, dict]:
    """Section name → its report, in the order given (a tqdm bar with ``progress``)."""
    from tqdm import tqdm

    report = {}
    with tqdm(names, desc="benchmark", unit="section", disable=not progress) as bar:
        for name in bar:
            bar.set_postfix_str(name)
            report[name] = run_section(name)
    return report


def cmd_benchmark(args) -> None:
    import json

    from cpp_mujoco.util.io import atomic_write_text
    from cpp_mujoco.util.tables import format_table

    unknown = set(args.only) - set(SECTIONS)
    if unknown:
        raise ValueError(
            f"unknown benchmark section(s) {sorted(unknown)}; known: {', '.join(SECTIONS)}"
        )
    check_output_file("--json", args.json, ".json")
    report = run_sections(args.only or list(SECTIONS), progress=progress_wanted(args))
    rows = [
        {"section": s, "measure": k, "value": f"{v:,.2f}" if isinstance(v, float) else v}
        for s, section in report.items()
        for k, v in section.items()
    ]
    print(format_table(rows, ["section", "measure", "value"]))
    atomic_write_text(args.json, json.dumps(report, indent=2))
    print(f"\nwritten: {args.json}")


def add_parser(sub) -> None:
    """Register ``cpp-mujoco benchmark`` (the command line's pattern: the parser sets ``func``)."""

    p = sub.add_parser("benchmark", help="measure env, planner, training and physics speed")
    p.add_argument(
        "--only", nargs="*", default=[],
        help=f"sections to run: {' '.join(SECTIONS)} (default: all)",
    )  # fmt: skip
    p.add_argument(
        "--json", default="out/benchmark.json",
        help="where to write the JSON report (default: %(default)s)",
    )  # fmt: skip
    add_progress_option(p)
    p.set_defaults(func=cmd_benchmark)
