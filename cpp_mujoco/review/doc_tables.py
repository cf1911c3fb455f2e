"""Tables that stand inside the documentation's pages, written from result files and maps.

``scripts/results_docs.py`` puts each between its markers in a page, so a page's numbers are
the files' (a test fails when they drift). Each function takes the parsed JSON it renders and
returns Markdown: a table and one line naming its conditions and its source.
"""

from __future__ import annotations

import numpy as np

from cpp_mujoco.maps import GridMap
from cpp_mujoco.review.optimum_table import policy_column
from cpp_mujoco.util.tables import format_table


def budget_range_text(conditions: dict) -> str:
    """``25..75`` (``every 5`` where a step was taken) of a result's ``budgets``."""
    b = conditions["budgets"]
    return f"{b['min']}..{b['max']}" + ("" if b["step"] == 1 else f" every {b['step']}")


def _pair(row: dict) -> str:
    return f"{row['landing_ratio']:.2%} / {row['coverage_ratio']:.2%}"


def maps_table(maps: list[GridMap]) -> str:
    """Each map's size and layers: landing, target (and how many of them are no-fly: seen only
    from beside), no-fly, and its digest."""
    lines = [
        "| map | size | landing | target | of them no-fly | no-fly | digest |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in maps:
        yellow = int((m.target & m.nfz).sum())
        lines.append(
            f"| {m.label} | {m.shape[0]}×{m.shape[1]} | {int(m.landing.sum())} | "
            f"{int(m.target.sum())} | {yellow} | {int(m.nfz.sum())} | `{m.digest}` |"
        )
    return "\n".join(lines)


def planners_table(data: dict, source: str) -> str:
    """Landing / coverage of each reference planner per map, beside the best missions."""
    rows = data["results"]
    policies = list(dict.fromkeys(r["policy"] for r in rows))
    maps = list(dict.fromkeys(r["map"] for r in rows))
    cell = {(r["map"], r["policy"]): r for r in rows}
    lines = [
        "| map | episodes | " + " | ".join(policies) + " | best missions (proven) |",
        "|---|---|" + "---|" * (len(policies) + 1),
    ]
    for m in maps:
        first = cell[(m, policies[0])]
        o = first["optimum"]
        lines.append(
            f"| {m} | {first['episodes']} | "
            + " | ".join(_pair(cell[(m, p)]) for p in policies)
            + f" | {o['coverage_ratio']:.2%} ({o['statuses'].get('optimal', 0)} / "
            f"{o['episodes_known']}) |"
        )
    budgets = {budget_range_text(r["conditions"]) for r in rows}
    lines += [
        "",
        f"Landing / coverage on the {rows[0]['backend']} backend, every landing cell × budgets "
        f"{', '.join(sorted(budgets))}; the random planner draws from seed 0. From `{source}`, "
        f"flown by `{data['command']}`.",
    ]
    return "\n".join(lines)


def held_out_table(sets: list[dict], abc: dict, sources: list[str]) -> str:
    """The general agent beside the planners on each held-out set (means over the maps) and on
    A, B and C (with the per-map agents), landing / coverage."""
    by_set = [{policy_column(s["policy"]): s for s in data["policies"]} for data in sets]
    abc_rows = abc["results"]
    maps = list(dict.fromkeys(r["map"] for r in abc_rows))
    head = [f"{d['map_set']['name']} ({d['map_set']['evaluated']} maps)" for d in sets]
    lines = [
        "| | " + " | ".join(head) + f" | {' / '.join(maps)} |",
        "|---|" + "---|" * (len(sets) + 1),
    ]
    labels = {"general": "general agent", "safe-greedy": "safe greedy",
              "beam-search": "beam search", "ddqn": "per-map paper agents"}  # fmt: skip
    for policy, label in labels.items():
        cells = [
            f"{s[policy]['mean_landing_ratio']:.2%} / {s[policy]['mean_coverage_ratio']:.2%}"
            if policy in s
            else "—"
            for s in by_set
        ]
        rows = [r for r in abc_rows if policy_column(r["policy"]) == policy]
        land = np.mean([r["landing_ratio"] for r in rows])
        cover = ", ".join(f"{r['coverage_ratio']:.2%}" for r in rows)
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {land:.2%} / {cover} |")
    best = {r["map"]: r["optimum"]["coverage_ratio"] for r in abc_rows}
    lines.append("| best missions (exact planner) | " + " | ".join("—" for _ in sets)
                 + " | " + ", ".join(f"{best[m]:.2%}" for m in maps) + " |")  # fmt: skip
    lines += [
        "",
        "Landing / coverage, the paper's protocol per map on the grid (every landing cell × every "
        "budget of the map's size class); on a held-out set the mean over its maps, on A, B and C "
        "the mean landing and each map's coverage; the best missions on the held-out sets are "
        "solved on a sample of their episodes ([The optimum](optimum.md)). From "
        + ", ".join(f"`{s}`" for s in sources)
        + ".",
    ]
    return "\n".join(lines)


def grid_wind_table(data: dict) -> str:
    """The grid's wind option per speed: each action kind's cost in units (mean ± std), the gust
    term's lag-1 correlation and skewness (``cpp_mujoco/grid/wind_costs.json``)."""
    kinds = data["kinds"]
    lines = [
        "| wind m/s | " + " | ".join(kinds) + " | lag-1 corr. | skewness |",
        "|---|" + "---|" * (len(kinds) + 2),
    ]
    for row in data["speeds"]:
        calm = row["wind_speed"] == 0
        cells = [
            f"{row['mean'][k]:.2f}" if calm else f"{row['mean'][k]:.2f} ± {row['std'][k]:.2f}"
            for k in kinds
        ]
        extra = ["–", "–"] if calm else [f"{row['lag1_correlation']:.2f}", f"{row['skewness']:.2f}"]
        lines.append(f"| {row['wind_speed']:g} | " + " | ".join(cells + extra) + " |")
    directions = ", ".join(f"{d:g}°" for d in data["directions"])
    lines += [
        "",
        f"{data['turbulence']} turbulence, {data['repeats']} gust histories × the wind from "
        f"{directions} per speed; one unit is {data['unit_energy_j']:.1f} J; physics digest "
        f"`{data['physics_digest']}`. From `cpp_mujoco/grid/wind_costs.json`, flown by "
        f"`{data['command']}`.",
    ]
    return "\n".join(lines)


def gust_tail_table(data: dict, source: str) -> str:
    """What a way home of k moves costs above its mean at the rated wind, MuJoCo beside the
    grid's wind option: standard deviation / 99th / 99.9th percentile in units."""
    rows = data["excess_over_mean_cost_units"]
    c = data["conditions"]
    lines = ["| k moves | MuJoCo | grid option |", "|---|---|---|"]
    for k in rows["mujoco"]:
        if not k.isdigit():
            continue
        cells = [f"{r[k]['std']:.2f} / {r[k]['p99']:.2f} / {r[k]['p99_9']:.2f}"
                 for r in (rows["mujoco"], rows["grid"])]  # fmt: skip
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
    lines += [
        "",
        f"{c['flights']} MuJoCo flights of {c['moves_per_flight']} random moves, "
        f"{c['wind_speed']:g} m/s from {c['directions']}, {c['turbulence']} turbulence; physics "
        f"digest `{c['physics_digest']}`. From `{source}`, flown by "
        f"`{data.get('command', 'python scripts/gust_tail.py')}`.",
    ]
    return "\n".join(lines)


# the paper's Table I (Theile et al., IROS 2020): each map's landing ratio over the full protocol
PAPER_LANDING = {"A": 0.9937, "B": 0.9978, "C": 0.9826}


def agents_table(metrics: dict[str, dict], abc: dict, source: str) -> str:
    """Each bundled per-map agent: its training (updates, episodes and wall time to the kept
    weights, from the agent file), its full-protocol landing and coverage beside the paper's
    landing ratio, the planners' coverage and the best missions'."""
    by = {(r["map"], policy_column(r["policy"])): r for r in abc["results"]}
    lines = [
        "| map | updates | episodes | wall time | landing | coverage | paper's landing "
        "| safe-greedy coverage | beam-search coverage | best missions |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, m in metrics.items():
        agent = by[(name, "ddqn")]
        landed = round(agent["landing_ratio"] * agent["episodes"])
        lines.append(
            f"| {name} | {m['updates']:,} | {m['episodes']:,} | {m['wall_s']:,.0f} s | "
            f"**{agent['landing_ratio']:.2%}** ({landed}/{agent['episodes']}) | "
            f"**{agent['coverage_ratio']:.2%}** | {PAPER_LANDING[name]:.2%} | "
            f"{by[(name, 'safe-greedy')]['coverage_ratio']:.2%} | "
            f"{by[(name, 'beam-search')]['coverage_ratio']:.2%} | "
            f"{agent['optimum']['coverage_ratio']:.2%} |"
        )
    lines += [
        "",
        "Updates, episodes and wall time to the kept weights (the run's best evaluation) from "
        "each agent file's metrics; the paper's landing ratio from its Table I; landing and "
        f"coverage over the full protocol (every landing cell × budgets 25..75) from `{source}`.",
    ]
    return "\n".join(lines)


COMPASS = {0.0: "N", 90.0: "E", 180.0: "S", 270.0: "W"}


def energy_table(data: dict, source: str) -> str:
    """Battery energy per action in budget units: steady wind, and mean ± std over gust
    histories in turbulence, per speed and direction (``physics/action_energy.py``)."""
    kinds, unit, turb = data["kinds"], data["unit_energy_j"], data["turbulence"]
    lines = [
        "| wind m/s | from | " + " | ".join(kinds) + " | "
        + " | ".join(f"{k} ({turb})" for k in kinds) + " |",
        "|---|---|" + "---|" * (2 * len(kinds)),
    ]  # fmt: skip
    for row in data["rows"]:
        steady, gusty = row["steady"], row["gusty"]
        cells = [f"{steady['mean_j'][k] / unit:.3f}" if k in steady["mean_j"] else "–"
                 for k in kinds]  # fmt: skip
        cells += [
            f"{gusty['mean_j'][k] / unit:.2f} ± {gusty['std_j'][k] / unit:.2f}"
            if k in gusty["mean_j"] else "–"
            for k in kinds
        ]  # fmt: skip
        speed = row["wind_speed"]
        where = COMPASS.get(row["wind_direction"], f"{row['wind_direction']:g}°") if speed else "–"
        lines.append(f"| {speed:g} | {where} | " + " | ".join(cells) + " |")
    lines += [
        "",
        f"One unit is {unit:.1f} J (a calm move's calibrated energy); {data['repeats']} gust "
        f"histories per row in {turb} turbulence (calm air has none). From `{source}`, flown by "
        f"`{data['command']}`.",
    ]
    return "\n".join(lines)


def transfer_table(data: dict, source: str) -> str:
    """The bundled per-map agents on the grid and flown in calm MuJoCo air over the same
    episodes: landing, coverage, energy per action, no-fly violations, crashes."""
    rows = data["results"]
    by = {(r["map"], r["backend"]): r for r in rows}
    maps = list(dict.fromkeys(r["map"] for r in rows))
    lines = [
        "| map | policy | episodes | grid landing | MuJoCo landing | grid coverage "
        "| MuJoCo coverage | J per action | no-fly violations | crashes |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for m in maps:
        g, p = by[(m, "grid")], by[(m, "mujoco")]
        if g["episodes"] != p["episodes"] or g["map_digest"] != p["map_digest"]:
            raise ValueError(f"map {m}: the grid and MuJoCo results are not the same episodes")
        lines.append(
            f"| {m} | {p['policy']} | {p['episodes']} | {g['landing_ratio']:.2%} | "
            f"{p['landing_ratio']:.2%} | {g['coverage_ratio']:.2%} | {p['coverage_ratio']:.2%} | "
            f"{p['energy_per_action_j']:.0f} | {p['nfz_violations']} | {p['crashes']} |"
        )
    budgets = {budget_range_text(r["conditions"]) for r in rows}
    lines += [
        "",
        f"Every landing cell × budgets {', '.join(sorted(budgets))}; map digests "
        + ", ".join(f"{m} `{by[(m, 'grid')]['map_digest']}`" for m in maps)
        + f". From `{source}`, flown by `{data['command']}`.",
    ]
    return "\n".join(lines)


def script_table(data: dict, name: str, source: str) -> str:
    """Table ``name`` of a script's tables file (``review.results.write_tables``) as the script
    rendered its cells, with the command that flew it."""
    table = data[name]
    command = data.get("command")
    if command is None:
        raise ValueError(f"{source} does not say which command flew it")
    body = format_table(table["rows"], table["columns"], style="markdown")
    title = table["title"][0].upper() + table["title"][1:]
    return f"{body}\n\n{title}. From `{source}`, flown by `{command}`."


def wind_agents_table(data: dict, source: str) -> str:
    """Per map, landing / coverage on the grid of the paper agent and the wind-robust agent in
    calm air and in the grid's wind, and of the safe greedy wind planner in that wind."""
    cells: dict[str, dict[str, str]] = {}
    heads: dict[str, str] = {}
    for r in data["results"]:
        wind = r["conditions"]["grid_config"]["wind"]
        policy = r["policy"]
        agent = "wind agent" if policy.endswith("-wind") else "paper agent"
        kind = agent if policy.startswith("ddqn") else policy
        where = "calm" if wind is None else f"{wind['max_speed']:g} m/s"
        step = r["conditions"]["budgets"]["step"]
        head = f"{kind}, {where}" + ("" if step == 1 else f" (every {step}th budget)")
        heads[head] = head
        cells.setdefault(r["map"], {})[head] = (
            f"{r['landing_ratio']:.2%} / {r['coverage_ratio']:.2%}"
        )
    order = sorted(heads, key=lambda h: ("m/s" in h, "safe" in h, "wind agent" in h))
    lines = ["| map | " + " | ".join(order) + " |", "|---|" + "---|" * len(order)]
    for m, row in cells.items():
        lines.append(f"| {m} | " + " | ".join(row.get(h, "—") for h in order) + " |")
    lines += [
        "",
        "Landing / coverage, the grid, every landing cell × budgets 25..75; the wind: every "
        "episode 9 m/s from N, E, S or W with the grid's gust costs. From "
        f"`{source}`, flown by `{data['command']}`.",
    ]
    return "\n".join(lines)


def occlusion_table(files: list[dict], sources: list[str]) -> str:
    """Physics vs grid coverage on a map set with obstacles, one row per field of view: the
    target cells the physics camera counted and the grid did not (extra), and the reverse."""
    lines = [
        "| view | episodes | grid's seen target cells | physics only (extra) "
        "| grid only (missing) | crashes |",
        "|---|---|---|---|---|---|",
    ]
    for data in files:
        t, first = data["totals"], data["results"][0]
        side = first["conditions"]["fov_side"]
        lines.append(
            f"| {side}×{side} | {t['episodes']} | {t['grid_seen']:,} | {t['extra']} "
            f"({t['extra_share']:.2%}) | {t['missing']} ({t['missing_share']:.2%}) "
            f"| {t['crashes']} |"
        )
    first = files[0]["results"][0]
    budgets = sorted({r["budget"] for d in files for r in d["results"]})
    lines += [
        "",
        f"Map set {first['conditions']['map_set']['name']}, each map's first landing cell with "
        f"budgets {', '.join(map(str, budgets))}: {first['policy']} on the grid, the same "
        "actions in calm MuJoCo air. From "
        + ", ".join(f"`{s}` (`{d['command']}`)" for s, d in zip(sources, files, strict=True))
        + ".",
    ]
    return "\n".join(lines)


def calibration_table(data: dict, source: str) -> str:
    """One calm move's energy (J) for each power model, the rotors alone and drawn from the pack
    (its internal loss on top, in %), and the hover power of the calibration."""
    by = {(r["power_model"], r["cell_resistance_ohm"] > 0): r for r in data["results"]}
    models = ("momentum", "forward-flight")
    ohm = next(r["cell_resistance_ohm"] for r in data["results"] if r["cell_resistance_ohm"] > 0)
    lines = [
        "| | momentum (hover) power model | forward-flight power model |",
        "|---|---|---|",
        "| rotors only (`battery_cell_resistance=0`) | "
        + " | ".join(f"{by[(m, False)]['unit_energy_j']:.2f}" for m in models)
        + " |",
        f"| drawn from the pack (default {ohm * 1000:g} mΩ per cell) | "
        + " | ".join(
            f"{by[(m, True)]['unit_energy_j']:.2f} "
            f"({by[(m, True)]['unit_energy_j'] / by[(m, False)]['unit_energy_j'] - 1:+.2%})"
            for m in models
        )
        + " |",
        "",
        f"The hover of the calibration draws {by[('momentum', False)]['hover_power_w']:.2f} W of "
        f"rotor load ({by[('momentum', True)]['hover_power_w']:.2f} W from the pack). From "
        f"`{source}`, flown by `{data['command']}`.",
    ]
    return "\n".join(lines)
