"""Demonstrations: every (landing cell, budget) episode of the planner, read back as n-step
transitions exactly as the planner flew them, and mixed into the trainer's minibatches."""

import numpy as np

from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.demonstrations import record_demonstrations
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.maps import GridMap
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.evaluate import evaluate

MAP = GridMap.from_ascii(["LL..TT", "L...TT", "..NN..", "TT...."])
CONFIG = GridConfig(min_budget=6, max_budget=12)


def test_demonstrations_are_the_planners_episodes():
    demos = record_demonstrations(MAP, CONFIG, make_planner("beam-search"), n_step=1, gamma=1.0)
    reference = evaluate(make_planner("beam-search"), MAP, config=CONFIG)
    assert demos.landing_ratio == reference.landing_ratio == 1.0
    assert demos.coverage_ratio == reference.coverage_ratio
    assert len(demos) == reference.steps.sum()  # one transition per action taken
    # with γ = 1 and n = 1, an episode's rewards sum to the planner's return
    t = demos.memory.transitions(demos.rows, demos.episodes)
    returns = np.bincount(demos.episodes, weights=t["return"], minlength=reference.returns.size)
    assert np.allclose(returns, reference.returns, atol=1e-5)
    first = demos.rows == 0
    assert np.array_equal(t["obs"][1][first, 0], reference.budgets[demos.episodes[first]])
    # exactly one termination per episode: its last transition, which does not bootstrap
    assert (t["discount"] == 0).sum() == reference.steps.size


def test_trainer_mixes_demonstrations_into_minibatches(tmp_path):
    cfg = TrainConfig(
        map="A", min_budget=8, max_budget=12, num_envs=8, batch_size=32, demo_fraction=0.25,
        learning_starts=64, total_updates=3, eval_every=10**9, checkpoint_every=10**9,
        final_eval=False, threads=1, guide_fraction=0.0,
    )  # fmt: skip
    trainer = Trainer(cfg, tmp_path)
    for _ in range(20):
        trainer.collect()
    batch = trainer.batch()
    assert batch["grid"].shape[0] == 32
    assert int(batch["demo"].sum()) == 8 and bool(batch["demo"][-8:].all())
    # demonstrated budgets come from the demonstration episodes (budget 8..12 at the start)
    assert float(batch["budget"][batch["demo"]].max()) <= 12
    trainer.run(progress=False)
    assert trainer.updates == 3
