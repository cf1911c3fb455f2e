"""Maps a user brings, trained beside the generated ones (``train-general --named-maps``): the
pool records them, the environments fly them at their share, the demonstrations cover them,
and a map that is not one, does not fit or is a held-out test map is refused before any run."""

import numpy as np
import pytest

from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.general_config import GeneralTrainConfig
from cpp_mujoco.agent.general_training import training_pool
from cpp_mujoco.agent.map_pool import NAMED_SEED, MapPool
from cpp_mujoco.agent.multi_map_env import MultiMapVectorEnv
from cpp_mujoco.agent.multi_map_replay import record_pool_demonstrations
from cpp_mujoco.agent.train import Trainer
from cpp_mujoco.map_sets.generator import generate_from_seed
from cpp_mujoco.map_sets.sets import map_set_spec
from cpp_mujoco.maps import load_map
from cpp_mujoco.maps.symmetry import SYMMETRIES
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.policy import policy_identity

from .test_general_agent import TINY


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    """Small nets on a shared 2-core machine: one torch thread."""


def test_the_pool_records_named_maps_and_pads_them():
    base = MapPool.generate((16, 32), 2, 0)
    pool = base.with_named([load_map("A"), load_map("C")])
    assert len(pool) == 6 and list(pool.named) == [4, 5]
    assert pool.seeds[4:] == [NAMED_SEED, NAMED_SEED]
    assert np.array_equal(pool.layers[4, :, :16, :16], load_map("A").layers)
    assert (pool.layers[5, 2, 16:] == 1).all()  # no-fly padding to the pool's side
    assert pool.configs[4].max_budget == 75  # a 16x16 map flies the 16x16 size class
    ident = pool.identity()
    assert ident["named"] == ["A (242dcad1db2a)", "C (e918b649ce3e)"]
    assert ident["seeds"] == [0, 1] and ident["digest"] != base.identity()["digest"]
    assert "named" not in base.identity() and not base.named.size


@pytest.mark.parametrize(
    "maps, match",
    [
        ([load_map("A"), load_map("A")], "already in the pool"),
        ([generate_from_seed(5, 32)], "larger than the pool's 16x16"),
        ([generate_from_seed(map_set_spec("heldout16-v1").first_seed + 3, 16)], "heldout16-v1"),
    ],
)
def test_maps_that_do_not_fit_are_refused(maps, match):
    with pytest.raises(ValueError, match=match):
        MapPool.generate((16,), 2, 0).with_named(maps)


def test_door_wall_training_maps_are_drawn_and_recorded():
    config = GeneralTrainConfig(sizes=(16,), maps_per_size=3, door_walls=1.0)
    pool = training_pool(config)
    expected = [generate_from_seed(seed, 16, door_wall=1.0).digest for seed in range(3)]
    assert [m.digest for m in pool.maps] == expected
    assert pool.identity()["generator"] == {"door_wall": 1.0}
    assert pool.flown_with(None).generator == {"door_wall": 1.0}
    plain = training_pool(GeneralTrainConfig(sizes=(16,), maps_per_size=3))
    assert "generator" not in plain.identity() and plain.digest != pool.digest
    with pytest.raises(ValueError, match="door_walls"):
        GeneralTrainConfig(door_walls=float("nan"))


def test_environments_fly_the_named_maps_at_their_share():
    pool = MapPool.generate((16,), 30, 0).with_named([load_map("B")])
    env = MultiMapVectorEnv(pool, 8, named_share=0.3)
    env.reset(seed=1)
    drawn = [env._draw_map() for _ in range(4000)]
    share = np.mean(np.asarray(drawn) == pool.named[0])
    assert abs(share - 0.3) < 0.03  # binomial sd 0.007
    generated = np.bincount([d for d in drawn if d != pool.named[0]], minlength=30)
    assert generated.min() > 50  # every generated map is still drawn (≈ 93 each)
    # a pool without named maps draws as runs from before the option did
    plain = MapPool.generate((16,), 30, 0)
    envs = [MultiMapVectorEnv(plain, 8, named_share=s) for s in (0.0, 0.3)]
    for env in envs:
        env.reset(seed=1)
        for _ in range(60):
            env.step(np.arange(8) % 5)
    assert np.array_equal(envs[0].map_index, envs[1].map_index) and envs[1].named_share == 0


def test_the_config_refuses_bad_named_options():
    with pytest.raises(ValueError, match="named_share"):
        GeneralTrainConfig(named_maps=("A",), named_share=float("nan"))
    with pytest.raises(ValueError, match="named_share > 0"):
        GeneralTrainConfig(named_maps=("A",), named_share=0.0)
    with pytest.raises(ValueError, match="repeat"):
        GeneralTrainConfig(named_maps=("A", "A"))
    with pytest.raises(ValueError, match="named_demo_share"):
        GeneralTrainConfig(named_maps=("A",), named_demo_share=float("nan"))
    with pytest.raises(ValueError, match="needs named_maps"):
        GeneralTrainConfig(named_demo_share=0.5)
    with pytest.raises(ValueError, match="named_demo_budget_step"):
        GeneralTrainConfig(named_maps=("A",), named_demo_budget_step=-1)
    stored = GeneralTrainConfig(named_maps=("A", "B")).to_dict()
    assert GeneralTrainConfig.from_dict(stored).named_maps == ("A", "B")
    old = {k: v for k, v in GeneralTrainConfig().to_dict().items() if "named" not in k}
    assert GeneralTrainConfig.from_dict(old).named_maps == ()  # a run from before the option


def test_named_demonstrations_fly_every_budget_and_fill_their_share():
    pool = MapPool.generate((16,), 2, 0).with_named([load_map("B")])
    b = int(pool.named[0])
    planner = make_planner("safe-greedy")
    coarse = record_pool_demonstrations(pool, [0, 1, b], planner, 3, 0.95, 25)
    fine = record_pool_demonstrations(pool, [0, 1, b], planner, 3, 0.95, [25, 25, 1], 0.4)
    on_b = [int((d.map_index == b).sum()) for d in (coarse, fine)]
    assert on_b[1] > 8 * on_b[0]  # 51 budgets against 3 (25, 50, 75)
    assert (fine.map_index != b).sum() == (coarse.map_index != b).sum()  # the rest as before
    rng = np.random.default_rng(0)
    drawn = fine.map_index[fine._draw(4000, rng)]
    assert abs((drawn == b).mean() - 0.4) < 0.03  # binomial sd 0.008
    assert {0, 1} <= set(drawn.tolist())
    uniform = coarse.map_index[coarse._draw(4000, rng)]
    assert abs((uniform == b).mean() - on_b[0] / len(coarse)) < 0.03
    with pytest.raises(ValueError, match="2 budget steps for 3 maps"):
        record_pool_demonstrations(pool, [0, 1, b], planner, 3, 0.95, [25, 1])
    with pytest.raises(ValueError, match="named and on generated"):
        record_pool_demonstrations(pool, [0, 1], planner, 3, 0.95, 25, 0.4)


def test_a_run_trains_on_its_named_map_with_demonstrations(tmp_path):
    config = GeneralTrainConfig(
        total_updates=20, **{**TINY, "learning_starts": 64, "named_maps": ("A",),
                             "named_share": 0.5, "named_demo_budget_step": 5,
                             "named_demo_share": 0.5},
    )  # fmt: skip
    trainer = Trainer(config, tmp_path)
    a = int(trainer.maps.pool.named[0])
    assert trainer.maps.pool.maps[a].label == "A" and len(trainer.maps.pool) == 5
    assert a in set(trainer.demos.map_index.tolist())  # demonstrations on the named map too
    assert trainer.demos.named_share == 0.5
    trainer.run(progress=False)
    flown = trainer.replay.map_index[: trainer.replay.pos].reshape(-1)  # rows written
    assert (flown == a).mean() > 0.2  # half the episodes start there
    agent = load_agent(tmp_path / "agent.pt")
    assert agent.metadata["train_maps"]["named"] == ["A (242dcad1db2a)"]
    assert list(agent.metadata["config"]["named_maps"]) == ["A"]


def test_a_run_trains_on_every_image_of_its_named_map_and_flies_symmetric(tmp_path):
    config = GeneralTrainConfig(
        total_updates=20, **{**TINY, "learning_starts": 64, "named_maps": ("C",),
                             "named_share": 0.5, "named_symmetries": True, "symmetric_q": True},
    )  # fmt: skip
    trainer = Trainer(config, tmp_path)
    images = [trainer.maps.pool.maps[i].name for i in trainer.maps.pool.named]
    assert images == ["C", *(f"C~{s.name}" for s in SYMMETRIES[1:])]
    assert set(trainer.maps.pool.named) <= set(trainer.demos.map_index.tolist())
    trainer.run(progress=False)
    agent = load_agent(tmp_path / "agent.pt")
    assert agent.symmetric_q and agent.metadata["symmetric_q"]
    assert len(agent.metadata["train_maps"]["named"]) == 8
    assert "d4-mean" in policy_identity(agent)["symmetric_q"]


def test_the_command_refuses_a_bad_named_map_before_claiming_the_folder(tmp_path, capsys):
    from cpp_mujoco.cli.main import main

    out = tmp_path / "run"
    for name, match in [("no-such-map", "no-such-map"), (str(tmp_path), "map")]:
        argv = ["train-general", "--out", str(out), "--named-maps", "A", name, "--sizes", "16",
                "--maps-per-size", "2", "--no-progress"]  # fmt: skip
        assert main(argv) == 2
        assert match in capsys.readouterr().err
        assert not out.exists() or not any(out.iterdir())
    assert training_pool(GeneralTrainConfig(sizes=(16,), maps_per_size=2), per_size=1).sizes == [16]
