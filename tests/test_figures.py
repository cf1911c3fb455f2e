"""Figures say what they show: each curve names its policy and backend, each title its map and
conditions (wind, turbulence, budgets), each axis its unit."""

import numpy as np
import pytest

from cpp_mujoco.maps import GridMap
from cpp_mujoco.planners import SafeGreedyPlanner
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.review.plots import (
    coverage_plot,
    trajectories_figure,
    trajectories_plot,
    wind_sweep_plot,
)

SMALL = GridMap.from_ascii(["LL.TT", "LL.TT", "....."], name="small")
WIND = {"wind_speed": 6.0, "wind_direction": 90.0, "turbulence": "moderate"}


@pytest.fixture(scope="module")
def grid_and_mujoco():
    """One policy on one map, on the grid and flown in MuJoCo in wind, the same episodes."""
    policy, budgets = SafeGreedyPlanner(), [5, 9]
    grid = evaluate(policy, SMALL, budgets=budgets, policy_name="ddqn[A]")
    physics = evaluate(
        policy, SMALL, backend="mujoco", budgets=budgets, policy_name="ddqn[A]", workers=1,
        env_kwargs=WIND,
    )  # fmt: skip
    return grid, physics


def test_the_transfer_figure_names_backend_policy_map_conditions_and_units(grid_and_mujoco):
    # before: both curves were labelled "ddqn[A]", the title "map small (grid)" only
    fig = coverage_plot(grid_and_mujoco)
    (ax,) = fig.axes
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend[0].startswith("ddqn[A] grid (land ")
    assert legend[1].startswith("ddqn[A] MuJoCo (land ")
    assert legend[2] == "upper bound"
    title = ax.get_title()
    assert "map small (grid vs MuJoCo" in title
    assert "MuJoCo: 6 m/s E + moderate turbulence" in title
    assert "grid: calm" in title and "budgets 5..9 step 4" in title
    assert ax.get_xlabel().startswith("movement budget (actions")
    assert ax.get_ylabel() == "coverage ratio (share of target cells)"


def test_the_wind_sweep_and_trajectory_figures_name_theirs(grid_and_mujoco, tmp_path):
    fig = wind_sweep_plot([grid_and_mujoco[1]])
    landing, coverage = fig.axes
    assert [t.get_text() for t in coverage.get_legend().get_texts()] == [
        "ddqn[A] MuJoCo, map small"
    ]
    assert landing.get_xlabel() == "steady wind (m/s; above 0: + moderate turbulence)"
    assert landing.get_ylabel() == "landing ratio (share of episodes)"
    assert "map small, MuJoCo under wind" in fig.get_suptitle()
    assert "budgets 5..9 step 4" in fig.get_suptitle()
    trajectories_figure(grid_and_mujoco[1], tmp_path / "t.png")  # titles built without error


def test_the_grid_curve_stays_visible_on_the_mujoco_curve(grid_and_mujoco):
    (ax,) = coverage_plot(grid_and_mujoco).axes
    grid, mujoco = ax.get_lines()[:2]
    assert grid.get_linestyle() == "--" and mujoco.get_linestyle() == "-"
    assert grid.get_zorder() > mujoco.get_zorder()  # drawn on top
    assert grid.get_marker() != mujoco.get_marker()
    assert grid.get_linewidth() < mujoco.get_linewidth()  # the wide line shows around it
    assert grid.get_color() == mujoco.get_color()  # one policy, one colour


def test_the_trajectory_legend_names_every_colour_and_the_start_is_no_map_colour(
    grid_and_mujoco,
):
    from matplotlib.colors import to_rgb

    from cpp_mujoco.grid.image import COLORS
    from cpp_mujoco.review.plots import START_COLOR, map_plot

    fig = trajectories_plot(grid_and_mujoco[0])
    (legend,) = fig.legends
    names = [t.get_text() for t in legend.get_texts()]
    for name in ("empty", "target", "no-fly", "target in no-fly", "landing", "start", "path"):
        assert name in names
    start = np.array(to_rgb(START_COLOR))
    assert all(np.abs(start - np.array(c) / 255).max() > 0.2 for c in COLORS.values())
    (legend,) = map_plot(SMALL).legends
    assert "target in no-fly" in [t.get_text() for t in legend.get_texts()]
