"""A short smoke training run improves over a random policy; CLI parsing; benchmark keys."""

import argparse
import dataclasses

import numpy as np
import pytest

from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.cli.train import add_parser, config_from_args
from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.protocol.evaluate import evaluate


class UniformRandom:
    def __init__(self, seed=0):
        self.rng = np.random.default_rng(seed)

    def act(self, obs):
        return self.rng.integers(5, size=len(obs["coverage"]))


def test_smoke_training_beats_random(tmp_path):
    cfg = TrainConfig(
        map="A", min_budget=8, max_budget=16, num_envs=16, total_updates=60,
        learning_starts=500, batch_size=64, learning_rate=1e-3, lr_warmup_updates=20,
        eval_every=10**9, checkpoint_every=10**9, final_eval=False, threads=1, guide_fraction=0.0,
        demo_fraction=0.0,  # pure temporal-difference learning from the agent's own experience
    )  # fmt: skip
    trainer = Trainer(cfg, tmp_path)
    trainer.run(progress=False)
    grid = GridConfig(min_budget=8, max_budget=16)
    trained = evaluate(trainer.agent(), "A", config=grid)
    random = evaluate(UniformRandom(), "A", config=grid)
    assert trained.returns.mean() > random.returns.mean() + 5
    assert trained.landing_ratio > random.landing_ratio


def test_cli_builds_config():
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(
        [
            "train",
            "--map",
            "B",
            "--seed",
            "3",
            "--out",
            "x",
            "--learning-rate",
            "1e-3",
            "--set",
            "n_step=1",
        ]
    )
    cfg = config_from_args(args)
    assert (cfg.map, cfg.seed, cfg.learning_rate, cfg.n_step, cfg.device) == (
        "B",
        3,
        1e-3,
        1,
        "cpu",
    )
    assert args.out == "x" and not args.resume
    paper = config_from_args(parser.parse_args(["train", "--out", "y", "--paper"]))
    assert (
        paper.num_envs,
        paper.n_step,
        paper.loss,
        paper.batch_size,
        paper.gamma,
        paper.tau,
        paper.beta,
    ) == (1, 1, "mse", 128, 0.95, 0.005, 0.1)


def test_guided_exploration_follows_planner_and_decays(tmp_path):
    from cpp_mujoco.planners import make_planner

    cfg = TrainConfig(
        map="B", num_envs=8, guide_fraction=0.5, guide_epsilon=0.0, guide_updates=100, threads=1
    )
    trainer = Trainer(cfg, tmp_path)
    assert trainer.guided_envs() == 4
    obs = {k: v.copy() for k, v in trainer.obs.items()}
    trainer.collect()
    expected = make_planner("safe-greedy").act({k: v[:4] for k, v in obs.items()})
    assert np.array_equal(trainer.replay.action[0, :4], expected)
    trainer.updates = 50
    assert trainer.guided_envs() == 2
    trainer.updates = 100
    assert trainer.guided_envs() == 0


def test_the_wind_planner_margin_option_reaches_guide_and_demonstrator(tmp_path, monkeypatch):
    import cpp_mujoco.agent.map_training as train_module

    taught = []
    real = train_module.record_demonstrations
    monkeypatch.setattr(
        train_module, "record_demonstrations",
        lambda m, cfg, planner, *a: taught.append(planner) or real(m, cfg, planner, *a),
    )  # fmt: skip
    cfg = TrainConfig(
        map="B", min_budget=8, max_budget=16, num_envs=8, threads=1, wind_max_speed=12,
        guide="safe-greedy-wind", demo_planner="beam-search-wind", wind_planner_sigmas=6.0,
    )  # fmt: skip
    trainer = Trainer(cfg, tmp_path)
    assert trainer.guide.margin.gusty_sigmas == 6.0
    assert [p.windy.margin.gusty_sigmas for p in taught] == [6.0]
    # the option sets the wind planners' margin only: without one it is refused, not ignored
    with pytest.raises(ValueError, match="wind_planner_sigmas .* needs guide or demo_planner"):
        TrainConfig(wind_planner_sigmas=6.0)
    with pytest.raises(ValueError, match="wind_planner_sigmas must be a finite number"):
        TrainConfig(wind_planner_sigmas=float("nan"), guide="safe-greedy-wind")


def test_train_help_states_each_default_once_and_explains_every_option(capsys):
    from cpp_mujoco.cli.main import main
    from cpp_mujoco.cli.train import _HELP, SHOWN

    names = [f.name for f in dataclasses.fields(TrainConfig)]
    assert set(_HELP) == set(names)
    assert all(len(_HELP[n].split()) >= 3 for n in names)  # a sentence, not the field's name
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    out = capsys.readouterr().out
    options = [line for line in out.splitlines() if line.startswith("  -")]
    assert len(options) <= 25  # the rest: --config FILE, --set KEY=VALUE
    text = " ".join(out.split())  # argparse wraps lines
    assert text.count("(default:") == len(SHOWN)  # each shown option once, the flags never
    assert "default: None" not in text and "--no-progress" in text and "--set KEY=VALUE" in text
    for name in SHOWN:
        assert f"{_HELP[name]} (default: {getattr(TrainConfig(), name)})" in text
    with pytest.raises(SystemExit):
        main(["train", "--list-settings"])
    listed = capsys.readouterr().out
    for name in names:  # every setting, with its default and its line
        assert f"  {name} = {getattr(TrainConfig(), name)!r}\n      {_HELP[name]}" in listed


def test_bad_option_value_names_the_option():
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["train", "--out", "x", "--eval-every", "0"])
    with pytest.raises(ValueError, match="invalid setting: --eval-every must be >= 1, got 0"):
        config_from_args(args)
    args = parser.parse_args(["train", "--out", "x", "--set", "gamma=2"])
    with pytest.raises(ValueError, match="invalid setting: .*gamma <= 1"):
        config_from_args(args)


def test_settings_come_from_a_file_then_set_then_the_options(tmp_path):
    from cpp_mujoco.util.settings import SettingsError, read_settings, to_toml

    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command"))
    toml = tmp_path / "run.toml"
    toml.write_text('gamma = 0.9\nloss = "mse"\nlearning_rate = 1e-3\nfinal_eval = false\n')
    argv = ["train", "--out", "x", "--config", str(toml), "--set", "learning_rate=2e-4"]
    args = parser.parse_args([*argv, "--set", "n_step=2", "--learning-rate", "3e-4"])
    config = config_from_args(args)
    assert (config.gamma, config.loss, config.n_step, config.final_eval) == (0.9, "mse", 2, False)
    assert config.learning_rate == 3e-4  # the option last
    assert config_from_args(parser.parse_args(argv)).learning_rate == 2e-4  # --set over the file
    resolved = tmp_path / "config.toml"
    resolved.write_text(to_toml(config))
    assert TrainConfig(**read_settings(TrainConfig, resolved)) == config  # the round trip
    for text, message in [
        ("gamma", "expected KEY=VALUE"),
        ("gama=0.9", "unknown setting 'gama'"),
        ("n_step=two", "n_step: expected int"),
        ("final_eval=maybe", "expected true or false"),
        ("learning_rate=nan", "not a number"),
    ]:
        with pytest.raises(SettingsError, match=message):
            config_from_args(parser.parse_args(["train", "--out", "x", "--set", text]))
    toml.write_text("gamma = [")
    with pytest.raises(SettingsError, match="not a TOML file"):
        config_from_args(parser.parse_args(["train", "--out", "x", "--config", str(toml)]))
    with pytest.raises(SettingsError, match="no such settings file"):
        config_from_args(parser.parse_args(["train", "--out", "x", "--config", "nope.toml"]))


@pytest.mark.parametrize("best_by, kept", [("return", [1, 3]), ("landing", [1, 2])])
def test_best_pt_keeps_the_evaluation_best_by_return_or_by_landing(
    tmp_path, monkeypatch, best_by, kept
):
    import cpp_mujoco.agent.train as train_module

    cfg = TrainConfig(
        map="B", min_budget=8, max_budget=16, num_envs=4, threads=1, guide_fraction=0.0,
        demo_fraction=0.0, best_by=best_by,
    )  # fmt: skip
    trainer = Trainer(cfg, tmp_path)
    evaluations = iter(
        [
            {"eval_return": 10.0, "eval_landing": 0.98, "eval_coverage": 0.8},
            {"eval_return": 5.0, "eval_landing": 1.00, "eval_coverage": 0.7},  # lands every time
            {"eval_return": 20.0, "eval_landing": 0.99, "eval_coverage": 0.9},  # crashes, covers
        ]
    )
    saved = []
    monkeypatch.setattr(trainer, "evaluate", lambda full=False: None)
    monkeypatch.setattr(trainer, "log", lambda res: next(evaluations))
    monkeypatch.setattr(trainer, "agent_state", lambda: trainer.updates)
    monkeypatch.setattr(train_module, "atomic_save", lambda state, path: saved.append(state))
    trainer._bar = type("Bar", (), {"write": staticmethod(lambda text: None)})()
    for trainer.updates in (1, 2, 3):
        trainer._evaluate_and_log()
    assert saved == kept
    with pytest.raises(ValueError, match="best_by"):
        TrainConfig(best_by="coverage")


def test_the_crash_reward_is_what_a_training_crash_pays(tmp_path):
    """``crash_reward`` sets the training MDP's crash reward (grid and physics fine-tuning): the
    same episodes pay the same rewards but for the crash; nonsense is refused."""
    from cpp_mujoco.grid.actions import NORTH

    rewards = []
    for crash in (-150.0, -600.0):
        cfg = TrainConfig(map="A", min_budget=2, max_budget=2, num_envs=4, crash_reward=crash,
                          threads=1, demo_fraction=0.0, guide_fraction=0.0)  # fmt: skip
        env = Trainer(cfg, tmp_path / str(crash)).env
        env.reset(seed=0)
        env.step(np.full(4, NORTH))
        _, reward, terminated, _, _ = env.step(np.full(4, NORTH))  # spent, unlanded: a crash
        assert terminated.all()
        rewards.append(reward)
    np.testing.assert_allclose(rewards[1] - rewards[0], -450.0)
    physics = dataclasses.replace(cfg, backend="mujoco", num_envs=5, physics_wind_speed=0.0)
    from cpp_mujoco.maps import load_map
    from cpp_mujoco.physics.envs.mixed_wind import MixedWindVectorEnv

    flown = MixedWindVectorEnv.for_training(physics, load_map("A"))
    assert [env.mdp.config.rewards.crash for env in flown.envs] == [-600.0]
    for bad in (float("nan"), 10.0):
        with pytest.raises(ValueError, match="crash_reward"):
            TrainConfig(crash_reward=bad)


def test_the_move_reward_is_what_a_training_move_pays(tmp_path):
    """``move_reward`` sets the training MDP's reward per move: the same episodes pay the same
    rewards but for each move's share; nonsense is refused."""
    from cpp_mujoco.grid.actions import NORTH

    rewards = []
    for move in (-0.2, 0.0):
        cfg = TrainConfig(map="A", min_budget=5, max_budget=5, num_envs=4, move_reward=move,
                          threads=1, demo_fraction=0.0, guide_fraction=0.0)  # fmt: skip
        env = Trainer(cfg, tmp_path / str(move)).env
        env.reset(seed=0)
        _, reward, _, _, _ = env.step(np.full(4, NORTH))
        rewards.append(reward)
    np.testing.assert_allclose(rewards[1] - rewards[0], 0.2)
    for bad in (float("nan"), 0.5):
        with pytest.raises(ValueError, match="move_reward"):
            TrainConfig(move_reward=bad)


def test_a_first_stage_stops_at_its_update_on_the_whole_runs_schedule(tmp_path):
    """``stop_after_updates`` ends the run there, with the learning rate and the guide where
    ``total_updates``' schedule has them, and a resume may carry the run on to the end."""
    base = dict(
        map="C", num_envs=8, batch_size=16, learning_starts=100, lr_warmup_updates=0,
        eval_every=10**9, checkpoint_every=10**9, final_eval=False, threads=1, demo_fraction=0.0,
        guide_updates=40,
        eval_budget_step=10**9,  # each stage's closing evaluation: the least and most budget only
    )  # fmt: skip
    first = Trainer(TrainConfig(total_updates=40, stop_after_updates=10, **base), tmp_path)
    first.run(progress=False)
    assert first.updates == 10
    whole = TrainConfig(total_updates=40, **base)
    assert first.learning_rate() == whole.learning_rate_at(10) < whole.learning_rate
    assert first.guided_envs() == round(0.5 * 0.75 * 8)
    again = Trainer(whole, tmp_path)
    assert again.resume() and again.updates == 10
    again.run(progress=False)
    assert again.updates == 40
    with pytest.raises(ValueError, match="stop_after_updates"):
        TrainConfig(stop_after_updates=float("nan"))
