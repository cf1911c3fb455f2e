"""``cpp-mujoco benchmark``: the speed figures, measured on this machine.

One pattern for every section: a module with ``run() -> dict`` (a flat dict of numbers),
registered in :data:`~cpp_mujoco.cli.parsers.SECTIONS` by module name and imported only when its
section runs — so the command line knows the sections without importing torch or MuJoCo. The
parser is in :mod:`cpp_mujoco.cli.parsers`.
"""

from __future__ import annotations

import importlib
import json
import os
import platform

from tqdm import tqdm

from cpp_mujoco.cli.options import check_output_file, progress_wanted
from cpp_mujoco.cli.parsers import SECTIONS
from cpp_mujoco.util.io import atomic_write_text
from cpp_mujoco.util.tables import format_table

__all__ = ["SECTIONS", "cmd_benchmark", "run_section", "run_sections"]


def run_section(name: str) -> dict:
    """Import the section's module and return its ``run()``."""
    if name not in SECTIONS:
        raise ValueError(f"unknown benchmark section {name!r}; known: {', '.join(SECTIONS)}")
    return importlib.import_module(SECTIONS[name]).run()


def run_sections(names: list[str], progress: bool = False) -> dict[str, dict]:
    """Section name → its report, in the order given (a tqdm bar with ``progress``)."""
    report = {}
    with tqdm(names, desc="benchmark", unit="section", disable=not progress) as bar:
        for name in bar:
            bar.set_postfix_str(name)
            report[name] = run_section(name)
    return report


def cmd_benchmark(args) -> None:
    unknown = set(args.only) - set(SECTIONS)
    if unknown:
        raise ValueError(
            f"unknown benchmark section(s) {sorted(unknown)}; known: {', '.join(SECTIONS)}"
        )
    check_output_file("--json", args.json, ".json")
    load_before = os.getloadavg()[0]
    report = run_sections(args.only or list(SECTIONS), progress=progress_wanted(args))
    machine = {  # what else ran decides the rates: a loaded machine gives lower bounds
        "cpus": os.cpu_count(), "load_average_1m_before": load_before,
        "load_average_1m_after": os.getloadavg()[0], "platform": platform.platform(),
        "python": platform.python_version(),
    }  # fmt: skip
    rows = [
        {"section": s, "measure": k, "value": f"{v:,.2f}" if isinstance(v, float) else v}
        for s, section in report.items()
        for k, v in section.items()
    ]
    print(format_table(rows, ["section", "measure", "value"]))
    command = "cpp-mujoco benchmark" + (f" --only {' '.join(args.only)}" if args.only else "")
    command += f" --json {args.json}"
    data = {**report, "machine": machine, "command": command}
    atomic_write_text(args.json, json.dumps(data, indent=2))
    print(f"\nwritten: {args.json}")
