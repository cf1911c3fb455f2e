"""The results pages and the README's headline table, written from committed result files only.

    python scripts/results_docs.py           # rewrite docs/results/*.md and README's headline
    python scripts/results_docs.py --check   # exit 1 if a committed page differs from the files

Reads the JSON under results/ (each result names its map and the map's digest, the policy, the
backend and the conditions it was flown under) and writes:

- README.md, between ``<!-- results:headline:start -->`` and ``<!-- results:headline:end -->``,
  and docs/results/index.md: the headline table, every bundled policy against the best missions
  on maps A, B and C (results/optimum_abc.json);
- docs/results/optimum.md: the exact planner's table of A, B and C (the one docs/optimum.md
  holds, from the same code) and the sampled held-out sets (results/optimum_<set>.json);
- docs/results/map_sets.md: every held-out set against its limit (the truth table: the general
  agent's network alone, results/network_alone_<set>.json; the bundled policy and the planners,
  results/map_set_<set>.json; the exact planner's sample, results/optimum_<set>.json), then the
  planners and the general agent over each set's whole protocol, when committed;
- tables inside the prose pages, between ``<!-- results:NAME:start -->`` and its end marker:
  the bundled maps (docs/maps.md, from the maps), the reference planners on A, B and C
  (docs/grid.md, results/planners_abc.json) and the general agent beside the planners on the
  held-out sets (docs/agent.md, results/map_set_*.json and results/optimum_abc.json).

Nothing else is read, so running it twice changes nothing, and tests/test_results_docs.py fails
when a committed page is not what this script writes.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "results"
PAGES = ROOT / "docs" / "results"
README = ROOT / "README.md"
HEADLINE = ("<!-- results:headline:start -->", "<!-- results:headline:end -->")
COMMAND = "`python scripts/results_docs.py`"
MAP_SET_COMMAND = "python scripts/results_flights.py map-set"
GENERATED = f"<!-- Written by {COMMAND[1:-1]} from results/; do not edit. -->"

# the headline's rows, best first: (the policy as results name it, what the row says)
HEADLINE_ROWS = (
    (
        "general+value-beam",
        "the bundled general policy: the general agent searching with its values "
        "(`general+value-beam`)",
    ),
    ("ddqn", 'bundled per-map agent (`load_agent("A")` …)'),
    ("general", 'general agent, network + its rules (`load_agent("general")`)'),
    ("beam-search", "beam search planner"),
    ("safe-greedy", "safe greedy planner"),
)


def load(name: str) -> dict:
    return json.loads((RESULTS / name).read_text(encoding="utf-8"))


def policy_key(policy: str) -> str:
    from cpp_mujoco.review.optimum_table import policy_column

    return policy_column(policy)


def shared(rows: list[dict], key: str) -> object:
    """The one value every row has for ``key`` (conditions the table states once)."""
    values = {json.dumps(r[key], sort_keys=True) for r in rows}
    if len(values) != 1:
        raise ValueError(f"the results differ in {key}: {sorted(values)}")
    return rows[0][key]


# ------------------------------------------------------------------------------ the headline
def headline(data: dict) -> str:
    """Each bundled policy's landing and coverage on A, B and C beside the best missions."""
    rows = data["results"]
    maps = list(dict.fromkeys(r["map"] for r in rows))
    backend = shared(rows, "backend")
    from cpp_mujoco.planners.beam_search import DEFAULT_WIDTH as WIDTH  # its name says so
    from cpp_mujoco.review.doc_tables import budget_range_text

    budgets = {budget_range_text(r["conditions"]) for r in rows}
    if len(budgets) != 1:
        raise ValueError(f"the headline's results were flown on different budgets: {budgets}")
    cell = {(r["map"], policy_key(r["policy"])): r for r in rows}
    first = {m: next(r for r in rows if r["map"] == m) for m in maps}
    lines = [
        "| policy | " + " | ".join(f"map {m}" for m in maps) + " |",
        "|---|" + "---|" * len(maps),
    ]
    best = []
    for m in maps:
        o = first[m]["optimum"]
        proven = o["statuses"].get("optimal", 0)
        best.append(
            f"{o['coverage_ratio']:.2%} (bound {o['bound_ratio']:.2%}; "
            f"{proven} / {o['episodes_known']} proven)"
        )
    lines.append("| **best missions** (exact planner) | " + " | ".join(best) + " |")
    for key, label in HEADLINE_ROWS:
        cells = []
        for m in maps:
            r = cell[(m, key)]
            gap = -r["optimum"]["gap_to_optimal"] * 100
            cells.append(f"{r['landing_ratio']:.2%} / **{r['coverage_ratio']:.2%}** ({gap:+.2f})")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    episodes = ", ".join(f"{m} {first[m]['episodes']}" for m in maps)
    digests = ", ".join(f"{m} `{first[m]['map_digest']}`" for m in maps)
    lines += [
        "",
        f"Landing / **coverage** (gap to the best missions over the same episodes, in points); "
        f"best missions: their mean coverage, the solver's proven bound, and how many episodes "
        f"are proven optimal. The paper's protocol on the {backend} backend: every landing cell "
        f"× budgets {budgets.pop()}, the agents acting greedily (the value beam: a beam of {WIDTH} "
        f"paths its Q-values rank, planned at the first step; {episodes} episodes; "
        f"map digests {digests}). "
        f"From `results/optimum_abc.json`; written by {COMMAND}.",
    ]
    return "\n".join(lines)


# ------------------------------------------------------------------------------ the pages
def index_page(data: dict, families: list[tuple[str, str]]) -> str:
    links = "\n".join(f"- [{title}]({name})" for name, title in families)
    return f"""{GENERATED}
# Results

Every table on these pages is written by {COMMAND} from the committed result files under
`results/` (and the grid's wind calibration, `cpp_mujoco/grid/wind_costs.json`) — each result
names its map (and the map's digest), the policy, the backend and the conditions it was flown
under. A test fails when a page differs from what the command writes.

## Headline: maps A, B and C against the optimum

{headline(data)}

## More

{links}
"""


def optimum_page() -> str:
    from cpp_mujoco.review.optimum_table import optimum_abc_table, optimum_sample_table

    parts = [
        GENERATED,
        "# Results: the optimum",
        "",
        'What the exact planner (`make_planner("optimal")`, [the model](../optimum.md)) found '
        "for every episode of the paper's protocol on maps A, B and C, and every bundled policy "
        "beside it:",
        "",
        optimum_abc_table(load("optimum_abc.json")),
    ]
    for path in sorted(RESULTS.glob("optimum_*.json")):
        data = json.loads(path.read_text(encoding="utf-8"))
        if "map_set" not in data:
            continue
        parts += [
            "",
            f"## {data['map_set']}: a sample of its episodes",
            "",
            optimum_sample_table(data),
        ]
    return "\n".join(parts) + "\n"


def map_set_page(paths: list[Path]) -> str:
    """The held-out sets' page: the truth table, then each set's full-protocol table."""
    from cpp_mujoco.review.map_set_page import map_set_page as page

    entries = []
    for path in paths:
        data = json.loads(path.read_text(encoding="utf-8"))
        key = path.stem.removeprefix("map_set_")  # the set, and "_stepN" where sampled
        more = [
            f"network_alone_{key}.json", f"optimum_{key}.json", f"symmetric_q_{key}.json",
            f"value_beam_{key}.json",
        ]  # fmt: skip
        entries.append(
            (path.name, data, *(load(f) if (RESULTS / f).is_file() else None for f in more))
        )
    decision = load("decision_time.json") if (RESULTS / "decision_time.json").is_file() else None
    return page(entries, GENERATED, MAP_SET_COMMAND, decision)


# ------------------------------------------------------------------ grid → MuJoCo (transfer)
TRANSFER = "transfer_abc.json"


def transfer_page(data: dict) -> str:
    from cpp_mujoco.review.doc_tables import transfer_table

    return "\n".join([
        GENERATED,
        "# Results: grid → MuJoCo",
        "",
        "The bundled per-map agents, trained on the grid only, flown unchanged by the MuJoCo "
        "quadrotor in calm air over the same episodes (how a grid action is flown: "
        "[physics](../physics.md)).",
        "",
        transfer_table(data, f"results/{TRANSFER}"),
    ]) + "\n"  # fmt: skip


# --------------------------------------------------------------- the grid's wind option
WIND_COSTS = ROOT / "cpp_mujoco" / "grid" / "wind_costs.json"


def grid_wind_page() -> str:
    from cpp_mujoco.review.doc_tables import grid_wind_table

    data = json.loads(WIND_COSTS.read_text(encoding="utf-8"))
    return "\n".join([
        GENERATED,
        "# Results: what an action costs in wind",
        "",
        "The grid's power-variation option (`GridConfig(wind=GridWind())`) charges each action "
        "what MuJoCo measured for its kind at the episode's wind: the mean ± standard deviation "
        "in budget units, and the gust term's lag-1 correlation and skewness.",
        "",
        grid_wind_table(data),
    ]) + "\n"  # fmt: skip


# ------------------------------------------------------------------------- held-out map sets


# ------------------------------------------------------- tables inside the prose pages
PLANNERS = "planners_abc.json"


ENERGY = "action_energy.json"


def in_page_tables() -> dict[Path, str]:
    """The prose pages with each generated table between its markers
    (``<!-- results:NAME:start -->`` … ``<!-- results:NAME:end -->``)."""
    from cpp_mujoco.maps import load_map
    from cpp_mujoco.review import doc_tables
    from cpp_mujoco.review.benchmark_table import benchmark_table
    from cpp_mujoco.review.optimum_table import replace_between

    docs = ROOT / "docs"
    tables: dict[Path, list[tuple[str, str]]] = {
        docs / "maps.md": [("maps", doc_tables.maps_table([load_map(m) for m in "ABC"]))],
    }
    wind = json.loads(WIND_COSTS.read_text(encoding="utf-8"))
    tables[docs / "grid.md"] = [("grid-wind", doc_tables.grid_wind_table(wind))]
    if (RESULTS / "gust_tail.json").is_file():
        table = doc_tables.gust_tail_table(load("gust_tail.json"), "results/gust_tail.json")
        tables[docs / "grid.md"].append(("gust-tail", table))
    if (RESULTS / PLANNERS).is_file():
        table = doc_tables.planners_table(load(PLANNERS), f"results/{PLANNERS}")
        tables[docs / "grid.md"].append(("planners", table))
    from cpp_mujoco.agent.checkpoint import load_checkpoint

    bundled = ROOT / "cpp_mujoco" / "agent" / "bundled"
    metrics = {m: load_checkpoint(bundled / f"{m}.pt")["metrics"] for m in "ABC"}
    table = doc_tables.agents_table(metrics, load("optimum_abc.json"), "results/optimum_abc.json")
    tables[docs / "agent.md"] = [("agents", table)]
    wind_page = []
    if (RESULTS / TRANSFER).is_file() and load(TRANSFER)["results"][0]["conditions"]["budgets"][
        "step"
    ] == 1:  # the full protocol only
        wind_page.append(
            ("transfer", doc_tables.transfer_table(load(TRANSFER), f"results/{TRANSFER}"))
        )
    if (RESULTS / ENERGY).is_file():
        wind_page.append(("energy", doc_tables.energy_table(load(ENERGY), f"results/{ENERGY}")))
    if (RESULTS / "rated_wind.json").is_file():
        table = doc_tables.script_table(load("rated_wind.json"), "rated_wind",
                                        "results/rated_wind.json")  # fmt: skip
        wind_page.append(("rated-wind", table))
    if (RESULTS / "rated_wind_each.json").is_file():
        table = doc_tables.script_table(
            load("rated_wind_each.json"), "rated_wind", "results/rated_wind_each.json"
        )
        wind_page.append(("rated-each", table))
        tables.setdefault(docs / "physics.md", []).append(("rated-each", table))
    if (RESULTS / "wind_sweep.json").is_file():
        table = doc_tables.script_table(load("wind_sweep.json"), "sweep", "results/wind_sweep.json")
        wind_page.append(("wind-sweep", table))
    if wind_page:
        tables[docs / "wind.md"] = wind_page
    if (RESULTS / "wind_agents_grid.json").is_file():
        table = doc_tables.wind_agents_table(
            load("wind_agents_grid.json"), "results/wind_agents_grid.json"
        )
        tables[docs / "agent.md"].append(("wind-agents", table))
    if (RESULTS / "transfer_abc_wind.json").is_file():
        table = doc_tables.transfer_table(
            load("transfer_abc_wind.json"), "results/transfer_abc_wind.json"
        )
        tables[docs / "agent.md"].append(("wind-transfer", table))
    if (RESULTS / "benchmark.json").is_file():
        table = benchmark_table(load("benchmark.json"), "results/benchmark.json")
        tables[docs / "scaling.md"] = [("benchmark", table)]
    if (RESULTS / "decision_time.json").is_file():
        table = benchmark_table(load("decision_time.json"), "results/decision_time.json")
        tables.setdefault(docs / "scaling.md", []).append(("decision", table))
    if (RESULTS / "calibration.json").is_file():
        table = doc_tables.calibration_table(load("calibration.json"), "results/calibration.json")
        tables[docs / "battery.md"] = [("calibration", table)]
    occlusion = sorted(RESULTS.glob("occlusion_city32-v1_fov*.json"))
    if occlusion:
        table = doc_tables.occlusion_table(
            [load(path.name) for path in occlusion], [f"results/{p.name}" for p in occlusion]
        )
        tables.setdefault(docs / "physics.md", []).append(("occlusion", table))
    sets = [RESULTS / f"map_set_{name}.json" for name in ("heldout16-v1", "heldout32-v1")]
    if all(path.is_file() for path in sets):
        table = doc_tables.held_out_table(
            [load(path.name) for path in sets], load("optimum_abc.json"),
            [f"results/{path.name}" for path in sets] + ["results/optimum_abc.json"],
        )  # fmt: skip
        tables[docs / "agent.md"].append(("held-out", table))
    pages = {}
    for path, parts in tables.items():
        text = path.read_text(encoding="utf-8")
        for name, table in parts:
            marks = (f"<!-- results:{name}:start -->", f"<!-- results:{name}:end -->")
            text = replace_between(text, *marks, table, where=path)
        pages[path] = text
    return pages


def render_all() -> dict[Path, str]:
    """Every file this script writes, path → its whole text (README with its headline)."""
    data = load("optimum_abc.json")
    from cpp_mujoco.review.optimum_table import replace_between

    families = [("optimum.md", "The optimum: every episode's best mission, and the policies")]
    pages = {PAGES / "optimum.md": optimum_page()}
    map_sets = sorted(RESULTS.glob("map_set_*.json"))
    if map_sets:
        families.append(("map_sets.md", "Held-out map sets: planners and the general agent"))
        pages[PAGES / "map_sets.md"] = map_set_page(map_sets)
    if (RESULTS / TRANSFER).is_file():
        families.append(("transfer.md", "Grid → MuJoCo: the bundled agents flown in physics"))
        pages[PAGES / "transfer.md"] = transfer_page(load(TRANSFER))
    families.append(("grid_wind.md", "What an action costs in wind: the grid's wind option"))
    pages[PAGES / "grid_wind.md"] = grid_wind_page()
    pages[PAGES / "index.md"] = index_page(data, families)
    readme = README.read_text(encoding="utf-8")
    pages[README] = replace_between(readme, *HEADLINE, headline(data), where=README)
    pages.update(in_page_tables())
    return pages


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--check", action="store_true", help="exit 1 if a page drifted; write nothing")
    args = p.parse_args(argv)
    drifted = []
    for path, text in render_all().items():
        old = path.read_text(encoding="utf-8") if path.is_file() else None
        if old == text:
            continue
        drifted.append(path.relative_to(ROOT))
        if not args.check:
            from cpp_mujoco.util.io import atomic_write_text

            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(path, text)
    if args.check and drifted:
        print("not what scripts/results_docs.py writes: " + ", ".join(map(str, drifted)))
        return 1
    for path in drifted:
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
