"""The held-out sets' results page: the truth table, the general agent's variants where flown,
then each set's policies (written by ``scripts/results_docs.py``)."""

from __future__ import annotations

from cpp_mujoco.review.doc_tables import budget_range_text
from cpp_mujoco.review.truth_table import (
    SYMMETRIC_Q,
    SYMMETRIC_Q_TEXT,
    TRUTH_TEXT,
    VALUE_BEAM_FILE,
    VALUE_BEAM_TEXT,
    agent_name,
    bundled_row,
    search_section,
    set_label,
    truth_table,
    variant_section,
)

SAMPLED_TEXT = (
    " A set whose whole protocol costs a policy more than a sitting is also flown at every n-th "
    "budget of its size class (the largest included), every policy of its rows on those same "
    "episodes: its rows say so beside the set's name."
)


def decision_text(decision: dict | None, source: str) -> list[str]:
    """What one UAV's decision costs the bundled policy and the network with its rules, from
    ``cpp-mujoco benchmark --only decision``'s report ``source`` (nothing without one)."""
    if decision is None:
        return []
    times = decision["decision"]

    def ms(policy: str, stat: str, digits: int = 1) -> str:
        return " / ".join(f"{times[f'{policy}_{n}x{n}_ms_{stat}']:.{digits}f}" for n in (16, 32))

    return [
        "",
        "Decision time, one UAV on one core, 16×16 / 32×32: the bundled policy "
        f"{ms('general_value_beam', 'mean')} ms per action on average, its first decision "
        f"(the whole plan) {ms('general_value_beam', 'max', 0)} ms; the network with its rules "
        f"{ms('general', 'mean')} ms, with the return rule only "
        f"{ms('general_network_alone', 'mean')} ms (`{decision['command']}`, {source}).",
    ]


def map_set_page(
    entries: list[tuple], generated: str, command: str, decision: dict | None = None
) -> str:
    """The held-out sets' page from ``(file name, map_set file, network-alone file, optimum
    sample, symmetric-Q file, value-beam file)`` per set (None: none): the truth table (and,
    with ``decision``, the benchmark's report of one UAV's decision time, what the bundled policy
    costs), the general agent with symmetric Q, then searching with its values, where flown,
    then each set's policies."""
    table = truth_table([(e[1], e[2], e[3], e[5]) for e in entries])
    sampled = any(e[1]["budgets"]["step"] != 1 for e in entries)
    parts = [
        generated,
        "# Results: held-out map sets",
        "",
        "The paper's protocol (every landing cell × every budget of the map's size class) on every "
        "map of a held-out set, on the grid; landing and coverage are means over the maps (each "
        "map weighs the same), the worst map's landing beside them." + SAMPLED_TEXT * sampled,
        "",
        "## Every set against its limit",
        "",
        table,
        "",
        TRUTH_TEXT,
        *decision_text(decision, "results/decision_time.json"),
    ]
    parts += variant_section([(e[1], e[4]) for e in entries], SYMMETRIC_Q, SYMMETRIC_Q_TEXT)
    parts += search_section([(e[1], e[3]) for e in entries])
    parts += variant_section([(e[1], e[5]) for e in entries], VALUE_BEAM_FILE, VALUE_BEAM_TEXT)
    for file_name, data, *_ in entries:
        spec = data["map_set"]
        agent = agent_name(bundled_row(data))
        option = {None: " --no-agent", "general": ""}.get(agent, f" --agent {agent}")
        step = data["budgets"]["step"]
        option += "" if step == 1 else f" --budget-step {step}"
        parts += [
            "",
            f"## {set_label(data)} ({spec['evaluated']} of its {spec['count']} maps, "
            f"{spec['size']}×{spec['size']})",
            "",
            "| policy | maps | episodes | landing | coverage | worst map's landing |",
            "|---|---|---|---|---|---|",
        ]
        for row in data["policies"]:
            parts.append(
                f"| {row['policy']} | {row['maps']} | {row['episodes']} | "
                f"{row['mean_landing_ratio']:.2%} | {row['mean_coverage_ratio']:.2%} | "
                f"{row['min_landing_ratio']:.2%} |"
            )
        parts += [
            "",
            f"The {data['backend']} backend, budgets {budget_range_text(data)}, "
            f"version {spec['version']} of the set. From `results/{file_name}`, flown by "
            f"`{command} --map-set {spec['name']}{option}` (`cpp-mujoco evaluate --map-set`).",
        ]
    return "\n".join(parts) + "\n"
