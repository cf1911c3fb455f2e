"""The general agent searching with its learned values against the limit: on each held-out set's
optimum sample, the coverage of beam search, the general agent with its rules and the bundled
general policy (the same agent's value beam), each with its gap to the best missions the exact
planner found on the same episodes. Which samples fit the set's bundled agent is decided by
:func:`~cpp_mujoco.review.truth_table.sample_fits`."""

from __future__ import annotations

VALUE_BEAM = "general+value-beam"
COLUMNS = (
    ("beam-search", "beam search"),
    ("general", "network + its rules"),
    (VALUE_BEAM, "bundled policy (value beam)"),
)
SEARCH_TEXT = (
    "Coverage (gap to the best missions found, ± its standard error, in points) on each set's "
    "optimum sample: episodes drawn uniformly over the protocol (`scripts/optimum_sample.py`, "
    "results/optimum_SET.json), every one solved by the exact planner from the best of the "
    "policies' missions. *Bundled policy*: the bundled general agent flown through a beam search "
    "of 32 paths per episode that its Q-values rank, its own mission the fallback (`cpp-mujoco "
    "evaluate --agent general+value-beam`; [The agents](../agent.md))."
)


def _cell(optimum: dict, name: str) -> str:
    p = optimum["policies"].get(name)
    if p is None:
        return "—"
    gap, error = p["gap_to_best"] * 100, p["gap_standard_error"] * 100
    return f"{p['coverage']:.2%} ({gap:+.2f} ± {error:.2f})"


def search_table(samples: list[dict]) -> str:
    """One row per optimum sample that flew the value beam: its episodes, the best missions
    (proven share) and each policy's coverage with its gap."""
    head = ["set", "sample episodes", "best missions (proven)", *(t for _, t in COLUMNS)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for optimum in samples:
        n = len(optimum["episodes"])
        proven = optimum["statuses"].get("optimal", 0)
        cells = [
            optimum["map_set"], str(n), f"{optimum['best_found']:.2%} ({proven}/{n})",
            *(_cell(optimum, name) for name, _ in COLUMNS),
        ]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
