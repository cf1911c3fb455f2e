"""Every held-out set in one table, against its limit: the general agent's network with the return
rule only, the network with its rules, the bundled policy (the same agent searching with its
values: ``general+value-beam``), the two planners, and how far above beam search the
exact planner's best missions and proven bound lie on a seeded sample of the same protocol.

The full-protocol columns and the sample columns are different episodes, so the sample's numbers
are given as gaps to beam search on that sample, never as a coverage beside the others."""

from __future__ import annotations

import json
from dataclasses import dataclass

from cpp_mujoco.review.search_table import SEARCH_TEXT, VALUE_BEAM, search_table

PLANNERS = ("safe-greedy", "beam-search")
TRUTH_TEXT = (
    "Coverage · landing, means over the set's maps. *Network + return rule*: the general agent's "
    "network with the return rule only (`--rule return-mask`; "
    "`python scripts/results_flights.py network-alone --map-set SET`, "
    "results/network_alone_SET.json). *Network + its rules*: the bundled general agent with its "
    "own rules (the return, revisit, finish and progress masks; `--agent general`); on the city "
    "sets the city-trained `general-city`, which reads obstacles and adds symmetric Q; — where "
    "no bundled agent fits the set. *Bundled policy*: the same agent searching with its values, "
    "the bundled general policy (`--agent general+value-beam`: a beam of 32 paths its Q-values "
    "rank, its own mission the fallback; one UAV's decision in results/decision_time.json; "
    "`python scripts/results_flights.py value-beam --map-set SET`, "
    "results/value_beam_SET.json); — where not flown with the present agent file and rules. "
    "The last two "
    "columns come from a seeded sample of the same protocol solved by the exact planner "
    "(`scripts/optimum_sample.py`, results/optimum_SET.json): how far the best missions found "
    "and the proven bound lie above beam search's missions on those episodes, in points of "
    "coverage; — where no sample is solved."
)


def set_label(data: dict) -> str:
    """A set file's name in tables: the set's, and the budgets it flew where not every one (a
    sample of the protocol: ``city50-v1 (every 10th budget)``)."""
    step = data["budgets"]["step"]
    name = data["map_set"]["name"]
    if step == 1:
        return name
    suffix = {1: "st", 2: "nd", 3: "rd"}.get(step % 10 if step % 100 not in (11, 12, 13) else 0)
    return f"{name} (every {step}{suffix or 'th'} budget)"


def _cell(row: dict | None) -> str:
    if row is None:
        return "—"
    return f"{row['mean_coverage_ratio']:.2%} · {row['mean_landing_ratio']:.2%}"


def bundled_row(data: dict) -> dict | None:
    """The set file's agent row flown with its own rules (``ddqn[NAME]``), if any."""
    rows = [
        r
        for r in data["policies"]
        if r["policy"].startswith("ddqn[") and "rules:" not in r["policy"]
    ]
    return rows[0] if rows else None


def agent_name(row: dict | None) -> str | None:
    """The agent a ``ddqn[NAME]`` row flew (None without a row)."""
    return row and row["policy"].removeprefix("ddqn[").removesuffix("]")


def network_row(data: dict | None) -> dict | None:
    """The network-alone file's one agent row (``ddqn[NAME, rules: return-mask]``)."""
    if data is None:
        return None
    rows = [r for r in data["policies"] if r["policy"].endswith("rules: return-mask]")]
    if len(rows) != 1:
        names = [r["policy"] for r in data["policies"]]
        raise ValueError(f"a network-alone result holds one return-mask agent row, not {names}")
    return rows[0]


def _sample_gaps(optimum: dict | None) -> tuple[str, str]:
    if optimum is None:
        return "—", "—"
    beam = optimum["policies"].get("beam-search")
    if beam is None:
        return "—", "—"
    n = len(optimum["episodes"])
    proven = optimum["statuses"].get("optimal", 0)
    best = (optimum["best_found"] - beam["coverage"]) * 100
    bound = (optimum["bound"] - beam["coverage"]) * 100
    return f"+{best:.2f} pt ({proven}/{n} proven)", f"+{bound:.2f} pt"


def _same_protocol(data: dict, other: dict, what: str = "network-alone") -> None:
    """Two full-protocol files of one set: same set version and maps, same conditions (but the
    policy, which a file of one policy names among them); ``what`` names the other file."""
    keys = ("name", "version", "count", "evaluated", "first_seed")
    same_set = [data["map_set"][k] for k in keys] == [other["map_set"][k] for k in keys]
    ours, theirs = (
        {k: v for k, v in d["conditions"].items() if k != "policy"} for d in (data, other)
    )
    if not same_set or ours != theirs:
        raise ValueError(f"{data['map_set']['name']}: the {what} file flew another protocol")


def _same_agent(data: dict, row: dict, what: str) -> None:
    """A one-agent file's row (``ddqn[NAME, rules: …]``) flew the set file's bundled agent."""
    bundled = bundled_row(data)
    if bundled is None or not row["policy"].startswith(
        f"{bundled['policy'].removesuffix(']')}, rules:"
    ):
        raise ValueError(
            f"{data['map_set']['name']}: the {what} file flew {row['policy']}, not the set's "
            f"bundled agent {bundled and bundled['policy']}"
        )


def agent_policy(data: dict) -> dict | None:
    """What the set file's bundled agent rows record of the policy (``conditions.policy``: its
    file's digest, network and every rule), one record for all its rows; None without one."""
    bundled = bundled_row(data)
    if bundled is None:
        return None
    records = {
        json.dumps(r["conditions"]["policy"], sort_keys=True)
        for r in data["rows"]
        if r["policy"] == bundled["policy"]
    }
    if len(records) != 1:
        raise ValueError(f"{data['map_set']['name']}: {bundled['policy']} flew as several policies")
    return json.loads(records.pop())


@dataclass(frozen=True)
class Variant:
    """A one-agent file beside a set file: the set's bundled agent with one thing added — its
    row's label is the bundled row's with ``suffix`` (inside the brackets with ``rules:``, as a
    rule changes it; after them, as search does), its policy record the bundled one plus the
    key ``added``."""

    what: str  # the file's kind, in errors and notes
    column: str  # its column's head
    suffix: str  # how its row's label ends
    added: str  # the key its policy record adds (a rule's flag, the search)
    family: str  # scripts/results_flights.py's family that flies it
    heading: str  # its section's

    def row(self, data: dict) -> dict:
        """The file's one agent row of this kind."""
        rows = [r for r in data["policies"] if r["policy"].endswith(self.suffix)]
        if len(rows) != 1:
            names = [r["policy"] for r in data["policies"]]
            raise ValueError(f"a {self.what} result holds one {self.family} agent row, not {names}")
        return rows[0]

    def same_agent(self, data: dict, row: dict) -> None:
        """Its row flew the set file's bundled agent (by label)."""
        if self.suffix.endswith("]"):  # a rule: inside the brackets
            return _same_agent(data, row, self.what)
        bundled = bundled_row(data)
        if bundled is None or row["policy"] != f"{bundled['policy']}{self.suffix}":
            raise ValueError(
                f"{data['map_set']['name']}: the {self.what} file flew {row['policy']}, not the "
                f"set's bundled agent {bundled and bundled['policy']}"
            )

    def fits(self, data: dict, variant: dict) -> bool:
        """The file flew the set file's bundled agent itself — the same file (digest) with the
        same rules — plus this variant's addition, nothing else."""
        return adds_only(agent_policy(data), variant["conditions"]["policy"], self.added)


def adds_only(ours: dict | None, theirs: dict, added: str | None = None) -> bool:
    """The policy record ``theirs`` is ``ours`` (the same file by digest, the same rules) with
    the key ``added`` and nothing else besides; where each was read from does not count."""
    if ours is None or (added is not None and added not in theirs):
        return False
    where = ("source", added)  # the path it was read from: the digest names the file
    return {k: v for k, v in ours.items() if k not in where} == {
        k: v for k, v in theirs.items() if k not in where
    }


SYMMETRIC_Q = Variant(
    "symmetric-Q", "+ symmetric Q", "+symmetric-q]", "symmetric_q", "symmetric-q",
    "The general agent with symmetric Q",
)  # fmt: skip
VALUE_BEAM_FILE = Variant(
    "value-beam", "+ value beam", "+value-beam", "search", "value-beam",
    "The general agent searching with its values, the whole protocol",
)  # fmt: skip


def symmetric_q_fits(data: dict, variant: dict) -> bool:
    """The symmetric-Q file flew the set file's bundled agent itself plus the rule."""
    return SYMMETRIC_Q.fits(data, variant)


def _same_maps(data: dict, optimum: dict) -> None:
    """An optimum sample drawn from the set's own maps (by digest)."""
    digests = {r["map_digest"] for r in data["rows"]}
    foreign = {e["map_digest"] for e in optimum["episodes"]} - digests
    if optimum["map_set"] != data["map_set"]["name"] or foreign:
        raise ValueError(
            f"{data['map_set']['name']}: the optimum sample holds maps not in the set: "
            f"{sorted(foreign)[:3]}"
        )


def truth_table(entries: list[tuple]) -> str:
    """One row per set from ``(map_set file, network-alone file, optimum sample[, value-beam
    file])``, each None where absent: coverage · landing over the full protocol, then the
    sample's gaps. A value-beam file flown with an earlier agent file or rules shows as —."""
    lines = [
        "| set | episodes | network + return rule | network + its rules "
        "| bundled policy (+ value beam) | safe greedy | beam search "
        "| best missions − beam (sample) | bound − beam (sample) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for data, network, optimum, *value_beam in entries:
        by_name = {r["policy"]: r for r in data["policies"]}
        episodes = {r["episodes"] for r in data["policies"]}
        if network is not None:
            _same_protocol(data, network)
            _same_agent(data, network_row(network), "network-alone")
            episodes.add(network_row(network)["episodes"])
        searching = _value_beam_row(data, value_beam[0] if value_beam else None)
        if searching is not None:
            episodes.add(searching["episodes"])
        if optimum is not None:
            _same_maps(data, optimum)
        if len(episodes) != 1:
            raise ValueError(f"{data['map_set']['name']}: policies flew different episode counts")
        bundled = bundled_row(data)
        label = f" ({bundled['policy']})" if agent_name(bundled) not in (None, "general") else ""
        best, bound = _sample_gaps(optimum)
        lines.append(
            f"| {set_label(data)} | {episodes.pop()} | {_cell(network_row(network))} | "
            f"{_cell(bundled)}{label} | {_cell(searching)} | {_cell(by_name.get(PLANNERS[0]))} | "
            f"{_cell(by_name.get(PLANNERS[1]))} | {best} | {bound} |"
        )
    return "\n".join(lines)


def _value_beam_row(data: dict, value_beam: dict | None) -> dict | None:
    """The value-beam file's row where it flew the set file's bundled agent, as it is now, over
    the same protocol (None: no file, or one of an earlier agent)."""
    if value_beam is None or not VALUE_BEAM_FILE.fits(data, value_beam):
        return None
    row = VALUE_BEAM_FILE.row(value_beam)
    _same_protocol(data, value_beam, VALUE_BEAM_FILE.what)
    VALUE_BEAM_FILE.same_agent(data, row)
    return row


SYMMETRIC_Q_TEXT = (
    "The bundled general agent with the symmetric-Q rule added (`--rule +symmetric-q`: the argmax "
    "of its Q-values averaged over the map's 8 rotations and mirror images, 8 network readings "
    "a step; `python scripts/results_flights.py symmetric-q --map-set SET`, "
    "results/symmetric_q_SET.json), beside the same agent with its own rules and the planners; "
    "the sets flown so far. On the paper's maps A, B and C, which it learned in their own "
    "orientation, the rule costs coverage, so the bundled general agent does not act with it."
)


def symmetric_q_row(data: dict) -> dict:
    """The symmetric-Q file's one agent row (``ddqn[NAME, rules: …+symmetric-q]``)."""
    return SYMMETRIC_Q.row(data)


def symmetric_q_table(entries: list[tuple[dict, dict]]) -> str:
    """:func:`variant_table` of symmetric-Q files."""
    return variant_table(entries, SYMMETRIC_Q)


def variant_table(entries: list[tuple[dict, dict]], variant: Variant) -> str:
    """One row per set from ``(map_set file, variant file)``: coverage · landing of the bundled
    policy, the same agent with the variant's addition, and the planners, over the full
    protocol."""
    lines = [
        f"| set | episodes | network + its rules | {variant.column} | safe greedy | beam search |",
        "|---|---|---|---|---|---|",
    ]
    for data, flown in entries:
        _same_protocol(data, flown, variant.what)
        row, bundled = variant.row(flown), bundled_row(data)
        if bundled is None or row["episodes"] != bundled["episodes"]:
            raise ValueError(f"{data['map_set']['name']}: no bundled row of the same episodes")
        variant.same_agent(data, row)
        if not variant.fits(data, flown):
            raise ValueError(
                f"{data['map_set']['name']}: the {variant.what} file flew another file or other "
                f"rules than the bundled policy's, not just {variant.added} added"
            )
        by_name = {r["policy"]: r for r in data["policies"]}
        lines.append(
            f"| {set_label(data)} | {row['episodes']} | {_cell(bundled)} | {_cell(row)} | "
            f"{_cell(by_name.get(PLANNERS[0]))} | {_cell(by_name.get(PLANNERS[1]))} |"
        )
    return "\n".join(lines)


def variant_section(entries: list[tuple[dict, dict | None]], variant: Variant, text: str):
    """The variant's table over the sets whose file flew the present bundled agent, then the
    sets whose file flew an earlier one, named."""
    flown = [(data, other) for data, other in entries if other is not None]
    if not flown:
        return []
    fits = [(data, other) for data, other in flown if variant.fits(data, other)]
    earlier = [set_label(data) for data, other in flown if not variant.fits(data, other)]
    parts = ["", f"## {variant.heading}"]
    if fits:
        parts += ["", variant_table(fits, variant), "", text]
    if earlier:
        parts += [
            "",
            f"Not shown: {', '.join(earlier)}, whose {variant.what} files were flown with an "
            "earlier file or rule set of the bundled agent (`python scripts/results_flights.py "
            f"{variant.family} --map-set SET` flies the present one).",
        ]
    return parts


VALUE_BEAM_TEXT = (
    "The bundled general agent with its rules flown through the beam search its Q-values rank "
    "(`--agent general+value-beam`: 32 paths per episode, its own mission the fallback; `python "
    "scripts/results_flights.py value-beam --map-set SET`, results/value_beam_SET.json), beside "
    "the same agent with its own rules and the planners, over the whole protocol (or the sample "
    "of budgets a row names); the sets flown so far. This is the bundled general policy "
    "(`--agent general+value-beam`)."
)


def sample_fits(optimum: dict, bundled: dict | None) -> bool:
    """An optimum sample's agent rows flew ``bundled`` (the set file's agent policy record), as
    the sample records them per policy (``policy_identities``): ``general`` the same file and
    rules, the value beam those with its search added."""
    identities = optimum.get("policy_identities", {})
    if VALUE_BEAM not in identities or "general" not in identities:
        return False
    beam = identities[VALUE_BEAM]
    return (
        adds_only(bundled, identities["general"])
        and adds_only(bundled, beam, "search")
        and beam["search"].get("name") == "value-beam"
    )


def search_section(entries: list[tuple[dict, dict | None]]) -> list[str]:
    """The value beam on the optimum samples that flew it with the set's bundled agent; the sets
    whose sample flew it with another are named."""
    flown = [(d, o) for d, o in entries if o is not None and VALUE_BEAM in o["policies"]]
    if not flown:
        return []
    fits = [o for d, o in flown if sample_fits(o, agent_policy(d))]
    parts = ["", "## Search with the learned values, against the limit"]
    if fits:
        parts += ["", search_table(fits), "", SEARCH_TEXT]
    if others := [d["map_set"]["name"] for d, o in flown if not sample_fits(o, agent_policy(d))]:
        parts += [
            "",
            f"Not shown: {', '.join(others)}, whose samples flew another file or rule set than "
            "the set's bundled agent (`python scripts/optimum_sample.py --map-set SET` flies the "
            "present one).",
        ]
    return parts
