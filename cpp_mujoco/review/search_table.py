"""The general agent searching with its learned values against the limit: on each held-out set's
optimum sample, the coverage of beam search, the bundled agent and the agent's value beam, each
with its gap to the best missions the exact planner found on the same episodes.

A sample's agent rows count only where they flew the set file's bundled agent — its file
(digest) and its rules, the value beam adding nothing but the search — which the sample records
per policy (``policy_identities``); a sample flown with another agent is named, not shown."""

from __future__ import annotations

VALUE_BEAM = "general+value-beam"
COLUMNS = (("beam-search", "beam search"), ("general", "bundled agent"), (VALUE_BEAM, "value beam"))
SEARCH_TEXT = (
    "Coverage (gap to the best missions found, ± its standard error, in points) on each set's "
    "optimum sample: episodes drawn uniformly over the protocol (`scripts/optimum_sample.py`, "
    "results/optimum_SET.json), every one solved by the exact planner from the best of the "
    "policies' missions. *Value beam*: the bundled general agent flown through a beam search of "
    "32 paths per episode that its Q-values rank, its own mission the fallback (`cpp-mujoco "
    "evaluate --agent general --value-beam`; [The agents](../agent.md))."
)


def _without(record: dict, *keys: str) -> dict:
    return {k: v for k, v in record.items() if k not in keys}


def sample_fits(optimum: dict, bundled: dict | None) -> bool:
    """The sample's agent rows flew ``bundled`` (the set file's agent policy record): the same
    file and rules, the value beam with its search added."""
    identities = optimum.get("policy_identities", {})
    if bundled is None or VALUE_BEAM not in identities or "general" not in identities:
        return False
    ours = _without(bundled, "source")
    beam = identities[VALUE_BEAM]
    return (
        _without(identities["general"], "source") == ours
        and _without(beam, "source", "search") == ours
        and beam.get("search", {}).get("name") == "value-beam"
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
