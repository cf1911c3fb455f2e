"""Fine-tuning in physics: the mixed-wind vector env and ``TrainConfig(backend="mujoco")``."""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
import pytest
import torch

from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.grid.wind import wind_velocity
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.envs.mixed_wind import MixedWindVectorEnv
from cpp_mujoco.physics.envs.vector import MuJoCoVectorEnv

# an open 5×6 map: landing strip in the middle row, targets around, one no-fly cell
MAP = GridMap.from_ascii(["TTTTTT", "T..N.T", "TLLLLT", "T....T", "TTTTTT"], name="open")
EAST = {"wind_speed": 9.0, "wind_direction": 90.0, "turbulence": "moderate"}
SOUTH = {"wind_speed": 6.0, "wind_direction": 180.0, "turbulence": "light"}


def _mixed(autoreset: str = "SameStep") -> MixedWindVectorEnv:
    return MixedWindVectorEnv([({}, 1), (EAST, 2), (SOUTH, 1)], MAP, autoreset_mode=autoreset)


def test_each_slot_flies_its_own_wind_as_a_plain_env_with_its_seed():
    """Slot j, seeded s + j, flies the episode a one-drone MuJoCoVectorEnv of its weather flies
    with that seed and the same actions: the same cells, rewards and energies to the bit, and
    it observes its own wind."""
    env = _mixed()
    assert env.num_envs == 4 and env.counts == [1, 2, 1]
    obs, _ = env.reset(seed=11, options={"budget": np.array([30, 30, 30, 30])})
    assert env.np_random_seed == (11, 12, 13, 14)
    weathers = [{}, EAST, EAST, SOUTH]
    expected = [
        wind_velocity(w.get("wind_speed", 0.0), w.get("wind_direction", 0.0)) for w in weathers
    ]
    np.testing.assert_allclose(obs["wind"], np.array(expected, dtype=np.float32))
    assert [c.turbulence for c in env.physics_configs] == ["none", "moderate", "moderate", "light"]
    plains = [MuJoCoVectorEnv(1, MAP, autoreset_mode="SameStep", **w) for w in weathers]
    singles = [p.reset(seed=[11 + j], options={"budget": 30})[0] for j, p in enumerate(plains)]
    for j, o in enumerate(singles):
        for key in o:
            np.testing.assert_array_equal(o[key][0], obs[key][j], err_msg=key)
    rng = np.random.default_rng(0)
    energies = []
    for _ in range(3):
        actions = rng.integers(0, 4, size=4)
        obs, reward, terminated, _, info = env.step(actions)
        for j, p in enumerate(plains):
            o, r, t, _, i = p.step(actions[j : j + 1])
            assert (r[0], t[0]) == (reward[j], terminated[j])
            assert i["energy_used_j"][0] == info["energy_used_j"][j]
            np.testing.assert_array_equal(o["position"][0], obs["position"][j])
            np.testing.assert_array_equal(o["wind"][0], obs["wind"][j])
        energies.append(info["energy_used_j"].copy())
    assert energies[-1][1] != energies[-1][2]  # one weather, two drones: their own gusts
    for e in [env, *plains]:
        e.close()


def test_one_weather_from_several_directions_is_one_batch_flying_each_direction():
    """Conditions that differ only in the wind's direction share one batch (one control tick),
    each drone with its own steady wind: still the flight of a plain env of its direction."""
    compass = [{**EAST, "wind_direction": d} for d in (0.0, 90.0, 180.0, 270.0)]
    env = MixedWindVectorEnv([({}, 1), *((w, 1) for w in compass)], MAP)
    assert env.counts == [1, 4]  # calm air, and one batch for the four directions
    assert [c.wind_direction for c in env.physics_configs][1:] == [0.0, 90.0, 180.0, 270.0]
    weathers = [{}, *compass]
    plains = [MuJoCoVectorEnv(1, MAP, **w) for w in weathers]
    obs, _ = env.reset(seed=5, options={"budget": np.full(5, 30)})
    for j, p in enumerate(plains):
        o, _ = p.reset(seed=[5 + j], options={"budget": 30})
        np.testing.assert_array_equal(o["wind"][0], obs["wind"][j])
    rng = np.random.default_rng(1)
    for _ in range(3):
        actions = rng.integers(0, 4, size=5)
        _, _, _, _, info = env.step(actions)
        for j, p in enumerate(plains):
            *_, i = p.step(actions[j : j + 1])
            assert i["energy_used_j"][0] == info["energy_used_j"][j], j  # to the bit
    used = info["energy_used_j"][1:]
    assert len(set(used.tolist())) == 4  # the four directions really fly differently


def test_autoreset_final_info_comes_through_for_the_slots_that_ended():
    """SameStep autoreset: the slots that landed are in ``final_info`` (``landed``,
    ``coverage_ratio``), masked by ``_final_info``, whichever sub-env they belong to; the slots
    of a sub-env where none ended are masked out (and zero)."""
    env = _mixed()
    env.reset(seed=3, options={"start": (2, 1)})  # all on the landing strip
    _, _, terminated, _, info = env.step(np.array([4, 1, 1, 1]))  # slot 0 lands; east: strip
    assert terminated.tolist() == [True, False, False, False]
    assert info["_final_info"].tolist() == [True, False, False, False]
    assert info["final_info"]["landed"][0] and info["final_info"]["coverage_ratio"][0] >= 0
    assert info["final_obs"]["budget"].shape == (4, 1)
    _, _, terminated, _, info = env.step(np.array([0, 0, 0, 4]))  # slot 3 lands
    assert terminated.tolist() == [False, False, False, True]
    assert info["_final_info"].tolist() == [False, False, False, True]
    assert info["final_info"]["landed"].tolist() == [False, False, False, True]
    env.close()


def test_state_dict_restores_the_generators_of_every_slot():
    env = _mixed("NextStep")
    env.reset(seed=21)
    state = env.state_dict()
    first, _ = env.reset()
    env.load_state_dict(state)
    again, _ = env.reset()
    for key in ("position", "budget", "wind"):
        np.testing.assert_array_equal(first[key], again[key])
    with pytest.raises(ValueError, match="4 slots"):
        env.load_state_dict({"rng": state["rng"][:2]})
    per_slot = env.reset(options={"budget": np.array([10, 20, 30, 40])})[0]["budget"]
    assert per_slot.ravel().tolist() == [10, 20, 30, 40]
    env.close()


def test_physics_conditions_split_the_slots_over_calm_air_and_each_direction():
    cfg = TrainConfig(map="B", backend="mujoco", wind_max_speed=12, num_envs=32)
    conds = cfg.physics_conditions()
    assert [n for _, n in conds] == [6, 7, 7, 6, 6]
    assert conds[0][0] == {} and [kw["wind_direction"] for kw, _ in conds[1:]] == [0, 90, 180, 270]
    assert {kw["wind_speed"] for kw, _ in conds[1:]} == {9.0}
    calm = TrainConfig(backend="mujoco", physics_wind_speed=0, num_envs=3)
    assert calm.physics_conditions() == [({}, 3)]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"backend": "bullet"}, "backend must be one of grid, mujoco"),
        ({"backend": "mujoco"}, "needs a network that observes the wind"),
        ({"backend": "mujoco", "wind_max_speed": 12, "num_envs": 4}, "3 windy slot"),
        ({"physics_wind_directions": "NX"}, "letters of NESW"),
        ({"physics_wind_directions": "NN"}, "letters of NESW"),
        ({"physics_turbulence": "stormy"}, "turbulence must be one of"),
        ({"physics_calm_share": 1.5}, "physics_calm_share must be in"),
        ({"physics_wind_speed": float("nan")}, "physics_wind_speed must be in"),
        ({"physics_threads": 0}, "physics_threads must be >= 1"),
    ],
)
def test_config_validation_names_the_bad_setting(kwargs, message):
    with pytest.raises(ValueError, match=message):
        TrainConfig(**kwargs)


def test_cli_and_the_general_agent():
    from cpp_mujoco.agent.general_config import GeneralTrainConfig
    from cpp_mujoco.cli.train import FINETUNE_EXAMPLE, add_parser, config_from_args

    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers())
    argv = FINETUNE_EXAMPLE.split()[1:]  # the documented command builds a valid config
    cfg = config_from_args(parser.parse_args(argv))
    assert (cfg.backend, cfg.init_from, cfg.physics_wind_speed) == ("mujoco", "B-wind", 9.0)
    bad = parser.parse_args(["train", "--out", "x", "--backend", "mujoco"])
    with pytest.raises(ValueError, match="--wind-max-speed"):
        config_from_args(bad)
    with pytest.raises(ValueError, match="grid only"):
        GeneralTrainConfig(backend="mujoco")


def test_tiny_finetuning_run_in_physics_checkpoints_and_resumes(tmp_path, one_thread):
    """From the bundled C-wind agent, a few updates on physics transitions (calm + N/E/S/W
    slots): the run starts as that agent, learns, writes its files, and a resume continues
    from its checkpoint with fresh episodes cut off from the old ones in the replay."""
    from cpp_mujoco.agent import load_agent
    from cpp_mujoco.agent.training_run import train

    cfg = TrainConfig(
        map="C", backend="mujoco", init_from="C-wind", wind_max_speed=12, num_envs=5,
        n_step=1, batch_size=8, buffer_size=100, learning_starts=5, total_updates=2,
        guide_fraction=0, demo_fraction=0, eval_every=100, eval_budget_step=50,
        final_eval=False, checkpoint_minutes=0, lr_warmup_updates=0, threads=1,
    )  # fmt: skip
    start = load_agent("C-wind").network.state_dict()
    first = train(cfg, tmp_path, progress=False)
    assert isinstance(first.env, MixedWindVectorEnv) and first.updates == 2
    winds = {tuple(w) for w in np.round(first.replay.wind[: first.replay.pos].reshape(-1, 2))}
    assert winds == {(0, 0), (0, -9), (-9, 0), (0, 9), (9, 0)}  # every weather was flown
    assert {"checkpoint.pt", "agent.pt", "best.pt", "log.csv"} <= {
        p.name for p in tmp_path.iterdir()
    }
    learned = load_agent(tmp_path / "agent.pt").network.state_dict()
    assert any(not torch.equal(start[k], learned[k]) for k in start)
    pos = first.replay.pos
    more = dataclasses.replace(cfg, total_updates=3)
    second = train(more, tmp_path, resume=True, progress=False)
    assert second.updates == 3 and len(second.history) == 2
    assert second.history[0]["loss"] == first.history[0]["loss"]  # the run's own history
    assert second.replay.terminated[pos - 1].all()  # the episodes in flight end at the cut
    assert not first.replay.terminated[pos - 1].all()
    assert second.env_steps > first.env_steps
