"""The results tables are the committed result files', and the README's example runs."""

import re
import runpy
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _script() -> dict:
    return runpy.run_path(str(ROOT / "scripts" / "results_docs.py"))


def test_every_committed_results_table_is_what_the_command_writes():
    # compared in memory: a page differs from the files -> run scripts/results_docs.py
    pages = _script()["render_all"]()
    assert ROOT / "README.md" in pages and ROOT / "docs" / "results" / "index.md" in pages
    for path, text in pages.items():
        assert path.is_file(), f"{path.relative_to(ROOT)} is missing: run scripts/results_docs.py"
        assert path.read_text(encoding="utf-8") == text, (
            f"{path.relative_to(ROOT)} is not what scripts/results_docs.py writes"
        )
    committed = set((ROOT / "docs" / "results").glob("*.md"))
    assert committed <= set(pages), "a page under docs/results/ the command does not write"


def test_writing_twice_changes_nothing():
    from cpp_mujoco.review.optimum_table import replace_between

    script = _script()
    readme = script["render_all"]()[ROOT / "README.md"]
    again = replace_between(
        readme, *script["HEADLINE"], script["headline"](script["load"]("optimum_abc.json"))
    )
    assert again == readme


def test_the_readme_types_no_percentage_outside_the_generated_tables():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    start, end = _script()["HEADLINE"]
    outside = text.split(start)[0] + text.split(end)[1]
    assert not re.findall(r"\d\s?%", outside)


def test_the_readme_example_runs(capsys):
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = text.split("<!-- example:start -->", 1)[1].split("<!-- example:end -->", 1)[0]
    code = block.split("```python\n", 1)[1].split("```", 1)[0]
    namespace: dict = {"__name__": "readme_example"}
    exec(compile(code, "README.md:example", "exec"), namespace)
    result = namespace["result"]
    assert result.landed.size > 0 and result.landing_ratio == 1.0
    assert namespace["searching"].landing_ratio == 1.0
    assert namespace["searching"].policy_name == "ddqn-general+value-beam"
    assert capsys.readouterr().out.strip()


def test_every_committed_result_names_its_map_policy_backend_and_conditions():
    import json

    from cpp_mujoco.maps import load_map

    for path in sorted((ROOT / "results").glob("*.json")):
        data = json.loads(path.read_text(encoding="utf-8"))
        # (benchmark.json's "physics" is a speed section of the machine, not per-map results)
        rows = [r for key in ("results", "physics") if isinstance(data.get(key), list)
                for r in data[key]]  # fmt: skip
        for row in rows:
            assert {"map", "map_digest", "policy", "backend", "conditions"} <= set(row), path
            if row.get("map_bundled"):
                assert row["map_digest"] == load_map(row["map"]).digest, (path, row["map"])
        for row in data.get("rows", []) if isinstance(data.get("rows"), list) else []:
            assert {"map", "map_digest", "policy"} <= set(row), path


def test_a_sampled_set_file_reads_the_files_of_its_own_sample(tmp_path):
    # map_set_SET_step10.json pairs with value_beam_SET_step10.json, never the whole protocol's
    import copy
    import json

    page_of = _script()["map_set_page"]
    page_of.__globals__["RESULTS"] = tmp_path
    data = json.loads((ROOT / "results" / "map_set_heldout16-v1.json").read_text("utf-8"))
    sampled = copy.deepcopy(data)
    sampled["budgets"]["step"] = sampled["conditions"]["budgets"]["step"] = 10
    whole = json.loads((ROOT / "results" / "value_beam_heldout16-v1.json").read_text("utf-8"))
    searching = copy.deepcopy(whole)
    searching["budgets"]["step"] = searching["conditions"]["budgets"]["step"] = 10
    searching["policies"][0]["mean_coverage_ratio"] = 0.1234
    files = {"map_set_heldout16-v1_step10.json": sampled,
             "value_beam_heldout16-v1.json": whole,
             "value_beam_heldout16-v1_step10.json": searching}  # fmt: skip
    for name, content in files.items():
        (tmp_path / name).write_text(json.dumps(content), encoding="utf-8")
    page = page_of([tmp_path / "map_set_heldout16-v1_step10.json"])
    rows = [x for x in page.splitlines() if x.startswith("| heldout16-v1 (every 10th budget) |")]
    assert len(rows) == 2  # the truth table's row and the value beam's
    assert all("| 12.34% · 100.00% |" in row for row in rows)
