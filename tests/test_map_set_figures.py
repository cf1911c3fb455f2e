"""Map-set results as figures (per-map coverage, example trajectories), drawn from the JSON
``evaluate --map-set`` writes; and map sets flown in MuJoCo."""

import importlib.util
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from matplotlib.collections import PathCollection
from PIL import Image

from cpp_mujoco.map_sets.sets import load_map_set, map_set_spec
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.map_sets import evaluate_map_set
from cpp_mujoco.review.map_set_figures import (
    MapSetFigureOptions,
    coverage_plot,
    load_map_set_result,
    merge_map_set_results,
    policy_label,
    trajectories_plot,
    write_map_set_figures,
)

ROOT = Path(__file__).resolve().parents[1]
POLICIES = ("safe-greedy", "random")


@pytest.fixture(scope="module")
def result_json(tmp_path_factory) -> Path:
    """Two planners over the first three maps of heldout16-v1 on the grid, budgets 25 and 75."""
    spec = map_set_spec("heldout16-v1")
    maps = load_map_set(spec.name, first=3)
    policies = [(name, make_planner(name)) for name in POLICIES]
    result = evaluate_map_set(spec, maps, policies, budget_step=50)
    return result.to_json(tmp_path_factory.mktemp("set") / "grid_heldout16-v1_first3.json")


def _texts(fig) -> str:
    return "\n".join(t.get_text() for t in fig.findobj(lambda a: hasattr(a, "get_text")))


def _not_blank(path: Path) -> None:
    pixels = np.asarray(Image.open(path).convert("RGB"))
    assert pixels.shape[0] > 200 and pixels.shape[1] > 200
    assert pixels.std() > 20  # not one flat colour
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 20  # the zones, markers, text


# ------------------------------------------------------------------------------- the JSON
def test_the_json_keeps_one_example_episode_per_map_and_policy(result_json):
    data = load_map_set_result(result_json)
    assert data["example_episode"]["budget"] == 75  # the middle of [25, 75]
    maps = {m.label: m for m in load_map_set("heldout16-v1", first=3)}
    for row in data["rows"]:
        ex, grid_map = row["example"], maps[row["map"]]
        first_landing = np.argwhere(grid_map.landing)[0].tolist()
        assert ex["start"] == first_landing and ex["budget"] == 75
        assert ex["cells"][0] == first_landing[0] * grid_map.shape[1] + first_landing[1]
        assert len(ex["cells"]) == ex["steps"] + 1  # the start, then one cell per action
        assert ex["steps"] <= 75 and 0 <= ex["coverage_ratio"] <= 1
    greedy = [r["example"] for r in data["rows"] if r["policy"] == "safe-greedy"]
    assert all(ex["landed"] for ex in greedy)


# ---------------------------------------------------------------------------- the figures
def test_the_coverage_figure_shows_every_policy_sorted_and_labelled(result_json):
    data = load_map_set_result(result_json)
    fig = coverage_plot([data], reference="safe-greedy")
    series = [c for c in fig.axes[0].collections if isinstance(c, PathCollection)]
    assert [s.get_label().split(":")[0] for s in series] == list(POLICIES)
    greedy = series[0].get_offsets()[:, 1]
    assert list(greedy) == sorted(greedy)  # maps in the reference policy's order
    landing = {(r["map"], r["policy"]): r["landing_ratio"] for r in data["rows"]}
    by_greedy = sorted(
        dict.fromkeys(r["map"] for r in data["rows"]),
        key=lambda m: next(
            r["coverage_ratio"] for r in data["rows"] if (r["map"], r["policy"]) == (m, POLICIES[0])
        ),
    )
    for s, policy in zip(series, POLICIES, strict=True):
        hollow = s.get_facecolors()[:, 3] == 0  # face 'none': not every episode landed
        assert list(hollow) == [landing[(m, policy)] < 1 for m in by_greedy]
    assert not (series[0].get_facecolors()[:, 3] == 0).any()  # safe greedy always lands
    legend = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().texts]
    assert any(t.startswith("safe-greedy: mean coverage") for t in legend)
    assert any(t.startswith("random: mean coverage") for t in legend)
    text = _texts(fig)
    for part in ("heldout16-v1 v1", "3 of 100 maps", "grid", "budgets 25..75 step 50"):
        assert part in text
    with pytest.raises(ValueError, match="policy 'beam-search' is not in heldout16-v1"):
        coverage_plot([data], reference="beam-search")


def test_the_trajectories_figure_has_a_panel_per_map_and_policy(result_json):
    data = load_map_set_result(result_json)
    fig = trajectories_plot(data, maps=["gen16-s1000002", "gen16-s1000000"])
    titles = [ax.get_title() for ax in fig.axes]
    assert len(fig.axes) == 4 and sum(t.startswith("random\n") for t in titles) == 2
    assert fig.axes[0].get_ylabel().startswith("gen16-s1000002")
    assert "budget 75" in _texts(fig) and "heldout16-v1 v1" in _texts(fig)
    with pytest.raises(ValueError, match="not in this result"):
        trajectories_plot(data, maps=["gen16-s1000099"])
    changed = json.loads(json.dumps(data))
    changed["rows"][0]["map_digest"] = "000000000000"
    with pytest.raises(ValueError, match="regenerates with digest"):
        trajectories_plot(changed, count=1)


def test_figures_are_written_from_the_json_alone(result_json, tmp_path):
    data = load_map_set_result(result_json)
    options = MapSetFigureOptions(reference="random", count=2)
    paths = write_map_set_figures({"r": data}, tmp_path, options=options)
    assert [p.name for p in paths] == ["r_coverage.png", "r_trajectories.png"]
    for path in paths:
        _not_blank(path)


def test_the_script_draws_a_result_file(result_json, tmp_path, capsys):
    spec = importlib.util.spec_from_file_location("msf", ROOT / "scripts/map_set_figures.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    assert script.main([str(result_json), "--out", str(tmp_path), "--count", "1"]) == 0
    stem = result_json.stem
    assert {p.name for p in tmp_path.iterdir()} == {
        f"{stem}_coverage.png",
        f"{stem}_trajectories.png",
    }
    old = json.loads(result_json.read_text())  # a result written before the examples
    for row in old["rows"]:
        del row["example"]
    (tmp_path / "old.json").write_text(json.dumps(old))
    capsys.readouterr()
    assert script.main([str(tmp_path / "old.json"), "--out", str(tmp_path / "o")]) == 0
    assert "no example episodes" in capsys.readouterr().err
    assert [p.name for p in (tmp_path / "o").iterdir()] == ["old_coverage.png"]
    assert script.main([str(result_json), "--reference", "nope", "--out", str(tmp_path)]) == 2
    assert script.main([str(tmp_path / "missing.json")]) == 2


def test_policy_labels_keep_an_agent_distinct():
    assert policy_label("ddqn[/runs/general-a/best.pt]") == "ddqn[general-a/best.pt]"
    assert policy_label("ddqn[general]") == "ddqn[general]"
    assert policy_label("safe-greedy") == "safe-greedy"


# ------------------------------------------------------------------------- MuJoCo backend
def _probe_set(monkeypatch):
    """A one-map set, heldout16-v1's map 39 (3 landing cells): the cheapest MuJoCo protocol."""
    spec = map_set_spec("heldout16-v1")
    probe = replace(
        spec, name="probe16-v1", first_seed=spec.first_seed + 39, count=1,
        digests=spec.digests[39:40],
    )  # fmt: skip
    monkeypatch.setattr("cpp_mujoco.map_sets.sets._read", lambda: {probe.name: probe})
    return probe


def test_a_map_set_flies_in_mujoco_and_says_so(monkeypatch, tmp_path, capsys):
    from cpp_mujoco.cli.main import main

    _probe_set(monkeypatch)
    argv = ["evaluate", "--map-set", "probe16-v1", "--backend", "mujoco", "--planner",
            "safe-greedy", "--budget-step", "50", "--workers", "1", "--no-progress",
            "--out", str(tmp_path)]  # fmt: skip
    assert main(argv) == 0
    assert "1 of 1 maps, budgets 25..75 step 50, mujoco" in capsys.readouterr().out
    data = json.loads((tmp_path / "mujoco_probe16-v1.json").read_text())
    assert data["backend"] == "mujoco" and {r["backend"] for r in data["rows"]} == {"mujoco"}
    assert data["rows"][0]["episodes"] == 6  # 3 landing cells x budgets 25, 75
    assert "physics_config" in data["conditions"]
    for kind in ("coverage", "trajectories"):
        _not_blank(tmp_path / f"mujoco_probe16-v1_{kind}.png")


def test_a_set_the_physics_cannot_build_fails_before_flying(monkeypatch):
    probe = _probe_set(monkeypatch)

    def no_arena(grid_map, env_kwargs):
        raise ValueError("XML Error: attribute 'data' has too much data")

    def never(*args, **kwargs):
        raise AssertionError("flew an episode")

    monkeypatch.setattr("cpp_mujoco.protocol.map_sets.make_env", no_arena)
    monkeypatch.setattr("cpp_mujoco.protocol.map_set_rows.evaluate", never)
    maps = load_map_set(probe.name)
    planner = [("safe-greedy", make_planner("safe-greedy"))]
    with pytest.raises(ValueError, match=r"'probe16-v1' \(16x16\) cannot be flown in MuJoCo"):
        evaluate_map_set(probe, maps, planner, budget_step=50, backend="mujoco")


def test_runs_of_one_set_merge_into_one_result_and_figure(result_json, tmp_path):
    """The planners flown here and an agent flown elsewhere, drawn as one: every policy's
    rows, each row keeping its run's conditions; other budgets or a policy twice are refused."""
    spec = map_set_spec("heldout16-v1")
    maps = load_map_set(spec.name, first=3)
    later = evaluate_map_set(spec, maps, [("beam-search", make_planner("beam-search"))], 50)
    later_json = later.to_json(tmp_path / "beam.json")
    script_spec = importlib.util.spec_from_file_location("msf", ROOT / "scripts/map_set_figures.py")
    script = importlib.util.module_from_spec(script_spec)
    script_spec.loader.exec_module(script)
    args = [str(result_json), str(later_json), "--merge", "--out", str(tmp_path / "m")]
    assert script.main([*args, "--count", "1"]) == 0
    stem = f"{result_json.stem}+beam"
    merged = load_map_set_result(tmp_path / "m" / f"{stem}.json")
    assert [p["policy"] for p in merged["policies"]] == [*POLICIES, "beam-search"]
    assert len(merged["rows"]) == 9 and all("backend" in r["conditions"] for r in merged["rows"])
    names = {p.name for p in (tmp_path / "m").iterdir()}
    assert {f"{stem}_coverage.png", f"{stem}_trajectories.png"} <= names
    _not_blank(tmp_path / "m" / f"{stem}_coverage.png")
    data = load_map_set_result(result_json)
    with pytest.raises(ValueError, match="two of the results"):
        merge_map_set_results([data, load_map_set_result(later_json), data])
    other = evaluate_map_set(spec, maps, [("beam-search", make_planner("beam-search"))], 25)
    with pytest.raises(ValueError, match="cannot merge"):
        merge_map_set_results([data, json.loads(json.dumps(other.to_dict()))])
