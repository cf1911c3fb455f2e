"""The truth table of the held-out sets: each column from its own file, refusing files that do
not belong together."""

import copy
import json
from pathlib import Path

import pytest

from cpp_mujoco.review.map_set_page import map_set_page
from cpp_mujoco.review.truth_table import (
    VALUE_BEAM_FILE,
    agent_policy,
    bundled_row,
    network_row,
    symmetric_q_row,
    symmetric_q_table,
    truth_table,
    variant_table,
)

RESULTS = Path(__file__).resolve().parent.parent / "results"


def load(name: str) -> dict:
    return json.loads((RESULTS / name).read_text(encoding="utf-8"))


def as_agent_file(data: dict, rules: str, coverage: float) -> dict:
    """A one-agent file made from a set file: its agent row relabelled as flown with ``rules``
    at ``coverage``, the planners gone."""
    out = copy.deepcopy(data)
    (row,) = [r for r in out["policies"] if r["policy"] == "ddqn[general]"]
    row["policy"] = f"ddqn[general, rules: {rules}]"
    row["mean_coverage_ratio"] = coverage
    out["policies"] = [row]
    return out


def as_network_alone(data: dict) -> dict:
    """A network-alone file made from a set file."""
    return as_agent_file(data, "return-mask", 0.5)


def test_row_holds_each_column_and_the_sample_gaps():
    data, optimum = load("map_set_heldout16-v1.json"), load("optimum_heldout16-v1.json")
    table = truth_table([(data, as_network_alone(data), optimum)])
    (row,) = [line for line in table.splitlines() if line.startswith("| heldout16-v1")]
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1] == str(data["policies"][0]["episodes"])
    assert cells[2] == "50.00% · 100.00%"
    assert cells[3] == f"{bundled_row(data)['mean_coverage_ratio']:.2%} · 100.00%"
    beam = optimum["policies"]["beam-search"]["coverage"]
    proven = optimum["statuses"]["optimal"]
    assert cells[4] == "—"  # no value-beam file given
    assert cells[7] == f"+{(optimum['best_found'] - beam) * 100:.2f} pt ({proven}/120 proven)"
    assert cells[8] == f"+{(optimum['bound'] - beam) * 100:.2f} pt"


def test_missing_columns_are_dashes_not_numbers():
    data = load("map_set_city50-v1.json")
    assert bundled_row(data) is None
    (row,) = truth_table([(data, None, None)]).splitlines()[2:]
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2] == cells[3] == cells[4] == cells[7] == cells[8] == "—"


def test_files_of_another_protocol_or_other_maps_are_refused():
    data = load("map_set_heldout16-v1.json")
    other = as_network_alone(data)
    other["conditions"]["budgets"]["step"] = 5
    with pytest.raises(ValueError, match="another protocol"):
        truth_table([(data, other, None)])
    with pytest.raises(ValueError, match="maps not in the set"):
        truth_table([(data, None, load("optimum_heldout32-v1.json"))])
    shorter = as_network_alone(data)
    shorter["policies"][0]["episodes"] -= 1
    with pytest.raises(ValueError, match="different episode counts"):
        truth_table([(data, shorter, None)])


def test_a_network_alone_file_of_another_agent_is_refused():
    data = load("map_set_heldout16-v1.json")
    other = as_network_alone(data)
    other["policies"][0]["policy"] = "ddqn[general-city, rules: return-mask]"
    with pytest.raises(ValueError, match="not the set's bundled agent ddqn\\[general\\]"):
        truth_table([(data, other, None)])


def test_network_alone_file_must_hold_the_return_rule_row():
    data = load("map_set_heldout16-v1.json")
    with pytest.raises(ValueError, match="one return-mask agent row"):
        network_row(data)


def test_the_committed_network_alone_file_fits_its_set():
    data, network = load("map_set_heldout16-v1.json"), load("network_alone_heldout16-v1.json")
    row = network_row(network)
    assert row["policy"] == "ddqn[general, rules: return-mask]"
    assert network["conditions"]["policy"]["finish_mask"] is False
    (line,) = truth_table([(data, network, None)]).splitlines()[2:]
    assert f"| {row['mean_coverage_ratio']:.2%} · {row['mean_landing_ratio']:.2%} |" in line


def as_symmetric_q(data: dict) -> dict:
    """A symmetric-Q file made from a set file: its bundled agent's policy record with the rule."""
    out = as_agent_file(data, "return-mask+revisit-mask+finish-mask+symmetric-q", 0.9)
    policy = {**agent_policy(data), "source": "elsewhere/general.pt", "symmetric_q": "d4-mean-v1"}
    out["conditions"]["policy"] = policy
    return out


def test_symmetric_q_rows_sit_beside_the_bundled_policy_and_the_planners():
    data = load("map_set_heldout16-v1.json")
    (row,) = symmetric_q_table([(data, as_symmetric_q(data))]).splitlines()[2:]
    cells = [c.strip() for c in row.strip("|").split("|")]
    by_name = {r["policy"]: r for r in data["policies"]}
    assert cells[0] == "heldout16-v1" and cells[3] == "90.00% · 100.00%"
    assert cells[2] == f"{bundled_row(data)['mean_coverage_ratio']:.2%} · 100.00%"
    assert cells[4] == f"{by_name['safe-greedy']['mean_coverage_ratio']:.2%} · 100.00%"
    assert cells[5] == f"{by_name['beam-search']['mean_coverage_ratio']:.2%} · 100.00%"


def test_symmetric_q_files_of_another_protocol_or_without_the_rule_are_refused():
    data = load("map_set_heldout16-v1.json")
    other = as_symmetric_q(data)
    other["conditions"]["budgets"]["step"] = 5
    with pytest.raises(ValueError, match="symmetric-Q file flew another protocol"):
        symmetric_q_table([(data, other)])
    with pytest.raises(ValueError, match="one symmetric-q agent row"):
        symmetric_q_row(as_network_alone(data))
    shorter = as_symmetric_q(data)
    shorter["policies"][0]["episodes"] -= 1
    with pytest.raises(ValueError, match="no bundled row of the same episodes"):
        symmetric_q_table([(data, shorter)])
    other_agent = as_symmetric_q(data)
    other_agent["policies"][0]["policy"] = other_agent["policies"][0]["policy"].replace(
        "general", "general-city"
    )
    with pytest.raises(ValueError, match="not the set's bundled agent"):
        symmetric_q_table([(data, other_agent)])


def test_a_symmetric_q_file_of_another_file_or_other_rules_is_refused_and_named():
    data = load("map_set_heldout16-v1.json")
    assert agent_policy(data)["digest"] and agent_policy(data)["finish_mask"] is True
    for change in ({"digest": "0123456789ab"}, {"progress_rule": "progress-v1"}):
        other = as_symmetric_q(data)
        other["conditions"]["policy"].update(change)
        with pytest.raises(ValueError, match="another file or other rules"):
            symmetric_q_table([(data, other)])
        entries = [("map_set_heldout16-v1.json", data, None, None, other, None)]
        page = map_set_page(entries, "<!-- generated -->", "flights")
        bundled = f"{bundled_row(data)['mean_coverage_ratio']:.2%} · 100.00% |"
        assert bundled in page.split("## The general agent with symmetric Q")[0]  # truth table
        assert "Not shown: heldout16-v1, whose symmetric-Q files" in page
        assert "90.00%" not in page
    entries = [("map_set_heldout16-v1.json", data, None, None, as_symmetric_q(data), None)]
    page = map_set_page(entries, "<!-- generated -->", "flights")
    assert "90.00% · 100.00%" in page and "Not shown" not in page


def test_an_agent_flown_as_several_policies_in_one_set_file_is_refused():
    data = copy.deepcopy(load("map_set_heldout16-v1.json"))
    (row, *_) = [r for r in data["rows"] if r["policy"] == "ddqn[general]"]
    row["conditions"]["policy"]["digest"] = "0123456789ab"
    with pytest.raises(ValueError, match="flew as several policies"):
        agent_policy(data)


def as_searched_sample(data: dict) -> dict:
    """The set's optimum sample as if it had flown the bundled agent and its value beam."""
    optimum = copy.deepcopy(load("optimum_heldout16-v1.json"))
    agent = agent_policy(data)
    optimum["policy_identities"] = {
        "general": dict(agent),
        "general+value-beam": {**agent, "search": {"name": "value-beam", "width": 32}},
    }
    optimum["policies"]["general+value-beam"] = {
        "coverage": 0.7777, "gap_to_best": -0.0123, "gap_standard_error": 0.0021,
    }  # fmt: skip
    return optimum


def test_the_value_beam_sits_beside_beam_search_and_the_agent_against_the_best_missions():
    data = load("map_set_heldout16-v1.json")
    optimum = as_searched_sample(data)
    page = map_set_page([("f.json", data, None, optimum, None, None)], "<!-- g -->", "flights")
    section = page.split("## Search with the learned values, against the limit")[1]
    (row,) = [line for line in section.splitlines() if line.startswith("| heldout16-v1")]
    cells = [c.strip() for c in row.strip("|").split("|")]
    beam = optimum["policies"]["beam-search"]
    assert cells[1] == "120"
    assert cells[2] == f"{optimum['best_found']:.2%} ({optimum['statuses']['optimal']}/120)"
    assert cells[3].startswith(f"{beam['coverage']:.2%} ({beam['gap_to_best'] * 100:+.2f} ±")
    assert cells[5] == "77.77% (-1.23 ± 0.21)"


def test_a_sample_of_another_agent_file_or_without_identities_is_named_not_shown():
    data = load("map_set_heldout16-v1.json")
    other = as_searched_sample(data)
    other["policy_identities"]["general+value-beam"]["digest"] = "0123456789ab"
    bare = as_searched_sample(data)
    del bare["policy_identities"]
    for optimum in (other, bare):
        page = map_set_page([("f.json", data, None, optimum, None, None)], "<!-- g -->", "flights")
        assert "Not shown: heldout16-v1, whose samples flew another file" in page
        assert "77.77%" not in page


def as_value_beam(data: dict) -> dict:
    """A value-beam file made from a set file: the bundled row searched, at 80 %."""
    out = copy.deepcopy(data)
    (row,) = [r for r in out["policies"] if r["policy"] == "ddqn[general]"]
    row["policy"], row["mean_coverage_ratio"] = "ddqn[general]+value-beam", 0.8
    out["policies"] = [row]
    out["conditions"]["policy"] = {**agent_policy(data), "search": {"name": "value-beam"}}
    return out


def test_the_value_beam_s_whole_protocol_sits_beside_the_bundled_policy_or_is_named():
    data = load("map_set_heldout16-v1.json")
    page = map_set_page([("f.json", data, None, None, None, as_value_beam(data))], "", "flights")
    section = page.split("## The general agent searching with its values, the whole protocol")[1]
    (row,) = [line for line in section.splitlines() if line.startswith("| heldout16-v1")]
    assert "| 80.00% · 100.00% |" in row and "Not shown" not in section.split("##")[0]
    other = as_value_beam(data)
    other["conditions"]["policy"]["digest"] = "0123456789ab"
    page = map_set_page([("f.json", data, None, None, None, other)], "", "flights")
    assert "Not shown: heldout16-v1, whose value-beam files" in page and "80.00%" not in page
    renamed = as_value_beam(data)
    renamed["policies"][0]["policy"] = "ddqn[general-city]+value-beam"
    with pytest.raises(ValueError, match="not the set's bundled agent"):
        variant_table([(data, renamed)], VALUE_BEAM_FILE)


def test_value_beam_column_from_its_file_and_a_dash_for_an_earlier_agent():
    data, searching = load("map_set_heldout16-v1.json"), load("value_beam_heldout16-v1.json")
    (line,) = truth_table([(data, None, None, searching)]).splitlines()[2:]
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[4] == f"{VALUE_BEAM_FILE.row(searching)['mean_coverage_ratio']:.2%} · 100.00%"
    earlier = copy.deepcopy(searching)
    earlier["conditions"]["policy"]["digest"] = "0123456789ab"  # another agent file
    (line,) = truth_table([(data, None, None, earlier)]).splitlines()[2:]
    assert [c.strip() for c in line.strip("|").split("|")][4] == "—"
    fewer = copy.deepcopy(searching)
    fewer["conditions"]["budgets"]["step"] = 5  # another protocol
    with pytest.raises(ValueError, match="value-beam file flew another protocol"):
        truth_table([(data, None, None, fewer)])


def test_the_page_says_what_a_decision_of_the_bundled_policy_costs():
    data, decision = load("map_set_heldout16-v1.json"), copy.deepcopy(load("decision_time.json"))
    decision["decision"]["general_value_beam_16x16_ms_mean"] = 12.34
    decision["decision"]["general_value_beam_32x32_ms_max"] = 2345.6
    page = map_set_page([("f.json", data, None, None, None, None)], "", "flights", decision)
    (line,) = [x for x in page.splitlines() if x.startswith("Decision time")]
    assert "the bundled policy 12.3 / " in line and "/ 2346 ms;" in line
    assert decision["command"] in line
    assert "Decision time" not in map_set_page([("f.json", data, None, None, None, None)], "", "")


def as_sampled(data: dict, step: int) -> dict:
    """A set file as flown at every ``step``-th budget (what its budgets and conditions say)."""
    out = copy.deepcopy(data)
    out["budgets"]["step"] = out["conditions"]["budgets"]["step"] = step
    return out


def test_a_set_flown_at_every_nth_budget_is_named_a_sample_wherever_shown():
    data = load("map_set_heldout16-v1.json")
    sampled = as_sampled(data, 10)
    entries = [("full.json", data, None, None, None, None)]
    page = map_set_page(entries, "", "flights")
    assert "every n-th budget" not in page and "th budget)" not in page
    entries.append(("map_set_heldout16-v1_step10.json", sampled, None, None, None,
                    as_value_beam(sampled)))  # fmt: skip
    page = map_set_page(entries, "", "flights")
    truth = page.split("## Every set against its limit")[1].split("##")[0]
    rows = [line for line in truth.splitlines() if line.startswith("| heldout16-v1")]
    assert [r.split("|")[1].strip() for r in rows] == [
        "heldout16-v1", "heldout16-v1 (every 10th budget)",
    ]  # fmt: skip
    assert "| 80.00% · 100.00% |" in rows[1] and "| 80.00%" not in rows[0]
    assert "every n-th budget of its size class" in page
    assert "## heldout16-v1 (every 10th budget) (100 of its 100 maps" in page
    assert "flights --map-set heldout16-v1 --budget-step 10`" in page
    searching = page.split("the whole protocol")[1]
    assert "| heldout16-v1 (every 10th budget) |" in searching
    with pytest.raises(ValueError, match="value-beam file flew another protocol"):
        truth_table([(data, None, None, as_value_beam(sampled))])  # a sample beside the whole


@pytest.mark.parametrize(
    ("step", "words"), [(2, "2nd"), (3, "3rd"), (5, "5th"), (11, "11th"), (21, "21st")]
)
def test_the_sample_s_budget_step_reads_as_an_ordinal(step, words):
    from cpp_mujoco.review.truth_table import set_label

    data = as_sampled(load("map_set_heldout16-v1.json"), step)
    assert set_label(data) == f"heldout16-v1 (every {words} budget)"
