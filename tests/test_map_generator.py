"""Generated maps: the checks, determinism per seed, size classes, ``maps generate``, the
held-out map sets and ``evaluate --map-set``."""

import json
from dataclasses import replace

import numpy as np
import pytest

import cpp_mujoco.map_sets.generator as generator
from cpp_mujoco.cli.main import main
from cpp_mujoco.map_sets.generator import GeneratorConfig, check_map, generate, generate_from_seed
from cpp_mujoco.map_sets.sets import (
    MapSetError,
    generate_map_set,
    load_map_set,
    map_set_names,
    map_set_spec,
)
from cpp_mujoco.map_sets.size_classes import budget_range, size_config
from cpp_mujoco.maps import GridMap, MapError, load_map
from cpp_mujoco.protocol.evaluate import protocol_budgets


def _map(rows: list[str]) -> GridMap:
    return GridMap.from_ascii(rows)


def _far_target(size: int = 32) -> GridMap:
    """Landing in the top-left corner, one target near the bottom-right: 2·48+1 = 97 actions
    reach a cell that sees it and come back."""
    rows = [["."] * size for _ in range(size)]
    rows[0][0] = "L"
    rows[25][25] = "T"
    return _map(["".join(r) for r in rows])


# ------------------------------------------------------------------------------------ checks
def test_a_valid_map_passes_the_checks():
    check_map(load_map("A"))
    check_map(_map(["LL..", "....", "...T", "...."]))


def test_a_landing_zone_in_two_parts_is_rejected():
    with pytest.raises(MapError, match="not 4-connected: it has 2 separate parts"):
        check_map(_map(["L...", ".L..", "...T", "...."]))  # diagonal neighbours are apart


def test_a_target_out_of_reach_is_rejected():
    # sealed behind a no-fly ring two cells thick: no free cell sees it
    sealed = ["L......", ".NNNNN.", ".NNNNN.", ".NNTNN.", ".NNNNN.", ".NNNNN.", "......."]
    with pytest.raises(MapError, match="no target cell is visible"):
        check_map(_map(sealed))
    # walled-in landing zone: the target is visible only from cells it cannot reach
    with pytest.raises(MapError, match="no target cell is visible"):
        check_map(_map(["LN.....", "NN.....", "......T"]))
    # too far for the budget: 97 actions needed
    with pytest.raises(MapError, match="within budget 75"):
        check_map(_far_target(), max_budget=75)


def test_the_check_takes_the_size_class_budget():
    check_map(_far_target())  # a 32x32 map: budgets up to 150


def test_generation_gives_up_with_a_clear_error(monkeypatch):
    def always_fails(grid_map, max_budget=None, fov_side=3):
        raise MapError("the test's rule")

    monkeypatch.setattr(generator, "check_map", always_fails)
    with pytest.raises(MapError, match=r"no valid 16x16 map in 3 attempts .*the test's rule"):
        generate(np.random.default_rng(0), 16, max_attempts=3)


def test_a_rejected_map_is_drawn_again_from_the_same_stream(monkeypatch):
    drawn = []
    real = generator.check_map

    def fails_once(grid_map, max_budget=None, fov_side=3):
        drawn.append(grid_map.digest)
        if len(drawn) == 1:
            raise MapError("the test's rule")
        real(grid_map, max_budget, fov_side)

    monkeypatch.setattr(generator, "check_map", fails_once)
    second = generate(np.random.default_rng(3), 16)
    assert second.digest == drawn[1] != drawn[0]
    monkeypatch.undo()
    assert generate(np.random.default_rng(3), 16).digest == drawn[0]


def test_bad_generator_arguments_are_errors():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="8..256"):
        generate(rng, 7)
    with pytest.raises(ValueError, match="unknown generator option.*'bogus'"):
        generate(rng, 16, bogus=1)
    with pytest.raises(ValueError, match="target_share"):
        GeneratorConfig(target_share=(0.5, 1.0))
    with pytest.raises(TypeError, match="numpy Generator"):
        generate(0, 16)


# ------------------------------------------------------------------------------ generation
def test_the_same_seed_gives_the_same_map():
    first = generate(np.random.default_rng(7), 16)
    again = generate(np.random.default_rng(7), 16)
    assert first.digest == again.digest and first.name == again.name
    digests = {generate(np.random.default_rng(s), 16).digest for s in range(6)}
    assert len(digests) == 6
    named = generate_from_seed(7)
    assert named.name == "gen16-s7" and named.label == "gen16-s7" and named.digest == first.digest
    other = generate_from_seed(7, target_share=(0.5, 0.55))  # other options: the name says so
    assert other.name == f"gen16-s7-{other.digest[:8]}"


@pytest.mark.parametrize(("size", "count"), [(8, 6), (16, 20), (32, 6)])
def test_generated_maps_are_valid(size, count):
    maps = [generate_from_seed(seed, size) for seed in range(count)]
    for m in maps:
        assert m.shape == (size, size)
        check_map(m)  # passes for its size class
        assert not (m.landing & m.nfz).any()
        assert 0.15 <= m.target.mean() <= 0.65
    assert len({m.digest for m in maps}) == count
    assert any((m.target & m.nfz).any() for m in maps)  # yellow cells
    assert any(m.nfz.any() for m in maps)
    starts = {tuple(np.argwhere(m.landing).min(axis=0)) for m in maps}
    assert any(r > 0 and c > 0 for r, c in starts)  # not always at the border


def _door_walls(m: GridMap) -> list[tuple[np.ndarray, int, int, np.ndarray]]:
    """(no-fly layer, first line, last line, door cells) of each wall across ``m``: a run of
    rows (of ``m`` or, for a vertical wall, of its transpose) closed to flight but for the same
    gap of 1-2 adjacent cells."""
    found = []
    for nfz, landing in ((m.nfz, m.landing), (m.nfz.T, m.landing.T)):
        gaps = {}
        for i in range(2, nfz.shape[0] - 2):
            gap = np.flatnonzero(~nfz[i] & ~landing[i])
            if 1 <= gap.size <= 2 and np.ptp(gap) == gap.size - 1:
                gaps[i] = tuple(gap)
        for i, gap in gaps.items():
            if gaps.get(i - 1) != gap:  # the first line of a run
                last = i + 1 if gaps.get(i + 1) == gap else i
                found.append((nfz, i, last, np.asarray(gap)))
    return found


def test_door_walls_cross_the_map_and_leave_the_door_open():
    maps = [generate_from_seed(seed, 16, door_wall=1.0) for seed in range(20)]
    for m in maps:
        check_map(m)
        # the door leads into open cells on both sides of the wall (no block closes it)
        assert any(
            not nfz[first - 1, gap].any() and not nfz[last + 1, gap].any()
            for nfz, first, last, gap in _door_walls(m)
        ), f"{m.name} has no wall with an open door"
    assert maps[0].name == f"gen16-s0-{maps[0].digest[:8]}"  # the option is in the name
    # at 0 no draw is made: the maps are those of the v1 sets' generator
    assert generate_from_seed(3, 16, door_wall=0.0).digest == generate_from_seed(3, 16).digest
    half = [bool(_door_walls(generate_from_seed(s, 16, door_wall=0.5))) for s in range(40)]
    assert 8 <= sum(half) <= 32  # about half (binomial sd 3.2), a few v1 maps have one too
    with pytest.raises(ValueError, match="door_wall"):
        generate_from_seed(3, 16, door_wall=1.5)


def test_size_classes():
    assert budget_range(16) == (25, 75) and budget_range(32) == (50, 150)
    assert budget_range(8) == (13, 38)
    config = size_config(32)
    assert (config.min_budget, config.max_budget) == (50, 150)
    assert len(protocol_budgets(config)) == 101


# ----------------------------------------------------------------------------------------- CLI
def test_maps_generate_writes_loadable_pngs(tmp_path, capsys):
    out = tmp_path / "gen"
    assert main(["maps", "generate", "3", "--seed", "5", "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines[:3]] == ["gen16-s5", "gen16-s6", "gen16-s7"]
    assert "budgets 25..75" in lines[3]
    for seed in (5, 6, 7):
        loaded = load_map(out / f"gen16-s{seed}.png")
        assert loaded.name == f"gen16-s{seed}"
        assert loaded.digest == generate_from_seed(seed).digest
    # a non-empty folder only with --overwrite
    assert main(["maps", "generate", "1", "--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert main(["maps", "generate", "1", "--size", "32", "--out", str(out), "--overwrite"]) == 0
    assert load_map(out / "gen32-s0.png").shape == (32, 32)
    argv = ["maps", "generate", "1", "--door-wall", "1", "--out", str(tmp_path / "doors")]
    assert main(argv) == 0
    door = generate_from_seed(0, 16, door_wall=1.0)
    assert load_map(tmp_path / "doors" / f"{door.name}.png").digest == door.digest


def test_maps_generate_refuses_bad_input(tmp_path, capsys):
    for bad in (["generate", "0"], ["generate", "2", "--size", "7"]):
        with pytest.raises(SystemExit) as exit_info:
            main(["maps", *bad, "--out", str(tmp_path / "x")])
        assert exit_info.value.code == 2
        assert "must be >=" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # --out is required
        main(["maps", "generate", "2"])
    assert "--out" in capsys.readouterr().err
    blocker = tmp_path / "file"
    blocker.write_text("x")
    for argv, message in [
        (["generate", "2", "--out", str(blocker / "sub")], "cannot create output folder"),
        (["generate", "2", "--out", str(blocker)], "is a file"),
        (["generate", "1", "--door-wall", "nan", "--out", str(tmp_path / "y")], "door_wall"),
    ]:
        assert main(["maps", *argv]) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err and len(err.splitlines()) == 1


# ---------------------------------------------------------------------------------- map sets
def test_heldout_sets_regenerate_to_the_committed_digests():
    assert {"heldout16-v1", "heldout32-v1"} <= set(map_set_names())
    for name, size, count in (("heldout16-v1", 16, 100), ("heldout32-v1", 32, 30)):
        spec = map_set_spec(name)
        assert (spec.size, spec.count, spec.first_seed) == (size, count, 1_000_000)
        maps = generate_map_set(spec)
        assert [m.digest for m in maps] == list(spec.digests)
        assert maps[0].name == f"gen{size}-s1000000"


def test_load_map_set_checks_digests(monkeypatch):
    assert len(load_map_set("heldout16-v1", first=2)) == 2
    with pytest.raises(
        MapSetError,
        match="unknown map set 'nope'; known: city32-v1, city50-v1, doors16-v1, field16-v1",
    ):
        load_map_set("nope")
    with pytest.raises(MapSetError, match="cannot take the first 101"):
        load_map_set("heldout16-v1", first=101)
    spec = map_set_spec("heldout16-v1")
    changed = ("000000000000", *spec.digests[1:])
    monkeypatch.setattr(
        "cpp_mujoco.map_sets.sets._read", lambda: {spec.name: replace(spec, digests=changed)}
    )
    with pytest.raises(MapSetError, match="gen16-s1000000 has digest .* the generator changed"):
        load_map_set("heldout16-v1", first=1)


def test_evaluate_on_a_map_set(tmp_path, capsys):
    argv = ["evaluate", "--map-set", "heldout16-v1", "--first", "2", "--planner", "safe-greedy"]
    assert main([*argv, "--budget-step", "25", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "gen16-s1000000" in out and "gen16-s1000001" in out and "mean of 2" in out
    assert "safe-greedy coverage" in out and "mean coverage" in out
    data = json.loads((tmp_path / "grid_heldout16-v1_first2.json").read_text())
    assert data["map_set"]["name"] == "heldout16-v1" and data["map_set"]["version"] == 1
    assert data["map_set"]["evaluated"] == 2 and data["map_set"]["complete"] is False
    assert data["budgets"] == {"min": 25, "max": 75, "step": 25}
    assert data["backend"] == "grid" and data["conditions"]["grid_config"]["max_budget"] == 75
    digests = map_set_spec("heldout16-v1").digests
    assert [(r["map_digest"], r["policy"]) for r in data["rows"]] == [
        (digests[0], "safe-greedy"),
        (digests[1], "safe-greedy"),
    ]
    landed = [r["landing_ratio"] for r in data["rows"]]
    assert data["policies"][0]["mean_landing_ratio"] == pytest.approx(np.mean(landed))


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--agent", "A"], "per-map agent"),
        (["--map", "A"], "replaces --map"),
        (["--wind-speed", "3"], "needs --backend mujoco"),
    ],
)
def test_map_set_refuses_what_it_cannot_run(tmp_path, capsys, extra, message):
    assert main(["evaluate", "--map-set", "heldout16-v1", *extra, "--out", str(tmp_path)]) == 2
    assert message in capsys.readouterr().err


def test_map_set_bad_names(tmp_path, capsys):
    assert main(["evaluate", "--map-set", "nope", "--out", str(tmp_path)]) == 2
    assert (
        "known: city32-v1, city50-v1, doors16-v1, field16-v1, field32-v1, heldout16-v1, "
        "heldout32-v1, scatter16-v1, scatter32-v1" in capsys.readouterr().err
    )
    assert main(["evaluate", "--first", "2", "--out", str(tmp_path)]) == 2
    assert "--first needs --map-set" in capsys.readouterr().err
