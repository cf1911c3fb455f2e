"""The protocol in wind from four directions, joined results, and flight at the rated wind."""

import numpy as np
import pytest

from cpp_mujoco.agent import load_agent
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.planners import RandomPlanner, SafeGreedyPlanner
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.protocol.wind import COMPASS, RATED_WIND, concatenate, evaluate_in_winds
from cpp_mujoco.review.results import rated_row, weather

SMALL = GridMap.from_ascii(["LL.TT", "LL.TT", "....."], name="small")


def test_joined_parts_equal_the_whole_protocol_episode_for_episode():
    whole = evaluate(SafeGreedyPlanner(), SMALL, budgets=[5, 6, 7, 9])
    parts = [evaluate(SafeGreedyPlanner(), SMALL, budgets=b) for b in ([5, 7], [6, 9])]
    joined = concatenate(parts)
    order = np.lexsort((joined.budgets, joined.starts[:, 1], joined.starts[:, 0]))
    ref = np.lexsort((whole.budgets, whole.starts[:, 1], whole.starts[:, 0]))
    for name in ("starts", "budgets", "landed", "coverage", "steps", "returns"):
        np.testing.assert_array_equal(getattr(joined, name)[order], getattr(whole, name)[ref])
    assert joined.landing_ratio == whole.landing_ratio
    assert joined.coverage_ratio == pytest.approx(whole.coverage_ratio)
    assert joined.upper_bound == whole.upper_bound
    # what the parts share is stated once; what differs (their budgets) per part, in order
    assert joined.conditions["episodes"] == whole.landed.size
    assert joined.conditions["backend"] == "grid"
    assert [p["budgets"] for p in joined.conditions["parts"]] == [
        {"min": 5, "max": 7, "step": 2}, {"min": 6, "max": 9, "step": 3},
    ]  # fmt: skip


def test_joining_unlike_results_is_an_error():
    greedy = evaluate(SafeGreedyPlanner(), SMALL, budgets=[5])
    with pytest.raises(ValueError, match="cannot join"):
        concatenate([greedy, evaluate(RandomPlanner(seed=0), SMALL, budgets=[6])])
    with pytest.raises(ValueError, match="flown twice"):
        concatenate([greedy, evaluate(SafeGreedyPlanner(), SMALL, budgets=[5, 6])])
    with pytest.raises(ValueError, match="nothing"):
        concatenate([])


def test_four_winds_fly_every_episode_once_each_direction_over_the_budget_range():
    result = evaluate_in_winds(
        SafeGreedyPlanner(), SMALL, 3.0, turbulence="light", budgets=[4, 5, 6, 7, 8], workers=1
    )
    starts = {(tuple(s), int(b)) for s, b in zip(result.starts, result.budgets, strict=True)}
    assert len(starts) == result.landed.size == 4 * 5  # 4 landing cells × 5 budgets, once
    parts = result.conditions["parts"]
    assert [p["physics_config"]["wind_direction"] for p in parts] == list(COMPASS)
    assert result.conditions["physics_config"]["wind_speed"] == 3.0  # shared
    assert result.conditions["physics_config"]["turbulence"] == "light"
    assert weather(result) == "3 m/s N/E/S/W + light turbulence"
    row = rated_row(result)
    assert row["weather"] == weather(result) and row["episodes"] == 20
    assert row["values"]["max_track_error_m"] == result.physics["max_track_error_m"].max()


def test_each_direction_flies_every_episode_from_all_four_and_says_so():
    result = evaluate_in_winds(
        SafeGreedyPlanner(), SMALL, 3.0, turbulence="light", budgets=[4, 8], workers=1,
        each_direction=True,
    )  # fmt: skip
    episodes = [(tuple(s), int(b)) for s, b in zip(result.starts, result.budgets, strict=True)]
    assert len(episodes) == 4 * len(set(episodes)) == 4 * 4 * 2  # 4 winds × 4 cells × 2 budgets
    parts = result.conditions["parts"]
    assert [p["physics_config"]["wind_direction"] for p in parts] == list(COMPASS)
    assert result.conditions["budgets"] == {"min": 4, "max": 8, "step": 4}  # shared by the winds
    assert weather(result) == "3 m/s each of N/E/S/W + light turbulence"
    with pytest.raises(ValueError, match="own conditions"):
        concatenate([result, result], repeated=True)


def test_a_result_flown_with_other_gust_histories_says_which():
    from cpp_mujoco.review.report_conditions import weather_summary

    rated = {"wind_speed": 9.0, "turbulence": "moderate"}
    assert weather_summary({"backend": "mujoco", "physics_config": rated}) == (
        "9 m/s + moderate turbulence"
    )
    other = {"backend": "mujoco", "physics_config": {**rated, "gust_seed": 1}}
    assert weather_summary(other) == "9 m/s + moderate turbulence, gust seed 1"


def test_calm_air_is_one_run_without_directions():
    result = evaluate_in_winds(SafeGreedyPlanner(), SMALL, 0.0, budgets=[5, 6], workers=1)
    assert weather(result) == "calm" and len(result.conditions["parts"]) == 1


def test_the_rated_wind_keeps_the_bundled_agent_out_of_no_fly_airspace():
    """A protocol subset of the full run (``scripts/rated_wind.py``): map B's agent, every
    landing cell, a short and a longer budget, 9 m/s from each direction + moderate turbulence."""
    result = evaluate_in_winds(
        load_agent("B"), "B", RATED_WIND["wind_speed"], turbulence=RATED_WIND["turbulence"],
        budgets=[25, 40], policy_name="ddqn[B]", workers=1,  # in this process: no spawn
    )  # fmt: skip
    assert result.landed.size == 8 * 2
    assert result.physics["nfz_violations"].sum() == 0
    # the margin: a no-fly border lies half a cell (2 m) from every reference point
    assert result.physics["max_track_error_m"].max() < 1.5
    # a crash in wind is an emergency landing where the UAV was, never a fall
    reasons = set(result.physics["crash_reason"].tolist()) - {""}
    assert all("emergency landing" in r or r == "budget exhausted before landing" for r in reasons)


def test_the_wind_sweep_script_writes_its_table_pivot_and_figure(tmp_path):
    """``scripts/wind_sweep.py`` on a small map, the planner with and without the guard, calm
    and 3 m/s: every point is a row with its weather, the pivot has one row per policy, the JSON
    carries the conditions, and the figure is written; an unknown policy is a one-line error."""
    import importlib.util
    import json
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "scripts" / "wind_sweep.py"
    spec = importlib.util.spec_from_file_location("wind_sweep_script", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    png = tmp_path / "small.png"
    GridMap.from_ascii(["LTTT", "TTTT", "TTTL"], name="small").save(png)
    args = ["--maps", str(png), "--speeds", "0", "3", "--sweep-step", "50", "--workers", "1"]
    args += ["--out", str(tmp_path), "--policies", "safe-greedy", "safe-greedy + guard"]
    assert script.main(args) == 0
    tables = json.loads((tmp_path / "wind_sweep.json").read_text())
    points = tables["points"]["rows"]
    assert [(r["policy"], r["weather"].split(" ")[0]) for r in points] == [
        ("safe-greedy", "calm"), ("safe-greedy", "3"),
        ("safe-greedy + guard", "calm"), ("safe-greedy + guard", "3"),
    ]  # fmt: skip
    guarded = points[2]["conditions"]["env_kwargs"]
    assert guarded["return_guard"] is True
    takeovers = [r["values"]["guard_takeovers"] for r in points]
    assert takeovers[:2] == [0, 0] and all(t >= 0 for t in takeovers[2:])  # counted, per point
    pivot = tables["sweep"]["rows"]
    assert [r["policy"] for r in pivot] == ["safe-greedy", "safe-greedy + guard"]
    assert all("%" in r["0 m/s"] and "%" in r["3 m/s"] for r in pivot)
    assert (tmp_path / "wind_sweep.png").stat().st_size > 10_000
    assert all(r["backend"] == "mujoco" for r in pivot)  # each pivot row says what it is
    page = (tmp_path / "index.html").read_text()  # the folder's page, headed by the command
    assert "python scripts/wind_sweep.py --maps" in page and 'src="wind_sweep.png"' in page
    with pytest.raises(SystemExit):
        script.main(["--maps", str(png), "--policies", "ddqn[Z]", "--out", str(tmp_path)])


def _rated_wind_script():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "scripts" / "rated_wind.py"
    spec = importlib.util.spec_from_file_location("rated_wind_script", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    return script


def test_rated_wind_flies_a_saved_agent_and_refuses_bad_options(tmp_path, capsys):
    script = _rated_wind_script()
    maps = [load_map("C")]
    runs = script.agent_variants(maps, "C-wind", guard=True)["C"]
    assert [(name, guard) for name, _, guard in runs] == [
        ("ddqn[C-wind]", False), ("ddqn[C-wind] + guard", True),
    ]  # fmt: skip
    assert runs[0][1].network.wind_inputs  # the saved agent itself, not a bundled stand-in
    for argv, message in (
        (["--agent", str(tmp_path / "missing.pt")], "missing.pt"),
        (["--agent", "C-wind", "--gust-seed", "-1"], "--gust-seed must be >= 0"),
    ):
        with pytest.raises(SystemExit):
            script.main([*argv, "--maps", "C", "--out", str(tmp_path / "out")])
        assert message in capsys.readouterr().err
    assert not (tmp_path / "out" / "rated_wind.json").exists()  # nothing flown, nothing written
