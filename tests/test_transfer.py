"""The protocol flown in MuJoCo: same episodes as the grid, physical figures, worker processes."""

import numpy as np
import pytest

from cpp_mujoco.maps import GridMap
from cpp_mujoco.planners import SafeGreedyPlanner
from cpp_mujoco.protocol.evaluate import evaluate

SMALL = GridMap.from_ascii(["LL.TT", "LL.TT", "....."], name="small")


@pytest.mark.parametrize("workers", [1, 2])
def test_mujoco_protocol_matches_the_grid_protocol_episode_for_episode(workers):
    budgets = [5, 9]
    grid = evaluate(SafeGreedyPlanner(), SMALL, budgets=budgets)
    physics = evaluate(SafeGreedyPlanner(), SMALL, backend="mujoco", budgets=budgets,
                       workers=workers)  # fmt: skip
    np.testing.assert_array_equal(physics.starts, grid.starts)
    np.testing.assert_array_equal(physics.budgets, grid.budgets)
    assert physics.landing_ratio == grid.landing_ratio == 1.0
    # the camera also sees while the UAV moves: physics covers at least what the grid covers
    assert (physics.coverage >= grid.coverage - 1e-9).all()
    summary = physics.summary()
    assert 400 < summary["energy_per_action_j"] < 600  # about one calibrated unit per action
    assert summary["nfz_violations"] == 0 and summary["crashes"] == 0
    assert (physics.trajectories[:, 0] == grid.trajectories[:, 0]).all()
