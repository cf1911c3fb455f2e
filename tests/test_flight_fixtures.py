"""The flights recorded before the physics implementations were merged into one
(:mod:`tests.flight_fixtures`: the single env, the vector env's numpy tick and its numba tick)
fly again, to 1e-9 relative; integers, flags, crash reasons and outcomes exactly."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from tests.flight_fixtures import CASES, PATHS, RECORD, Recording, compare, fly, load

_CASES = {case.name: case for case in CASES}


@pytest.fixture(scope="module")
def recorded() -> tuple[dict, dict[str, Recording]]:
    return load()


def test_the_fixtures_hold_every_case_and_path(recorded):
    """A case added, dropped or changed since the recording must be recorded again, not
    replayed against numbers flown with other settings."""
    meta, recordings = recorded
    assert meta["cases"] == {name: case.describe() for name, case in _CASES.items()}, (
        f"the cases differ from the recorded ones: record them again with `{RECORD}`"
    )
    assert sorted(recordings) == sorted(f"{c}.{p}" for c in _CASES for p in PATHS)


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("name", list(_CASES))
def test_the_recorded_flights_fly_again(recorded, name: str, path: str):
    """Pose, observation, reward, flags and every info number after every step, as recorded."""
    compare(recorded[1][f"{name}.{path}"], fly(_CASES[name], path), f"{name} ({path})")


def test_missing_fixtures_are_refused_clearly(tmp_path: Path):
    with pytest.raises(FileNotFoundError, match=r"flights\.json.*flights\.npz.*tests\.flight_fix"):
        load(tmp_path)
    (tmp_path / "flights.json").write_text(json.dumps({"recordings": {}}), encoding="utf-8")
    with pytest.raises(FileNotFoundError, match=r"missing: \S*flights\.npz; record them"):
        load(tmp_path)


def test_a_drifted_number_flag_or_reason_fails(recorded):
    """The comparison itself: a float off by 1e-8 relative, a flipped flag, another reason."""
    want = recorded[1]["failures.single"]
    assert want.arrays["info_energy_used_j"][1, 3] > 0  # drone 3 flew its first move
    compare(want, copy.deepcopy(want), "itself")
    drifted = copy.deepcopy(want)
    drifted.arrays["info_energy_used_j"][1, 3] *= 1 + 1e-8
    with pytest.raises(AssertionError, match="info_energy_used_j"):
        compare(want, drifted, "drifted")
    flipped = copy.deepcopy(want)
    flipped.arrays["terminated"][1, 3] = ~flipped.arrays["terminated"][1, 3]
    with pytest.raises(AssertionError, match="terminated"):
        compare(want, flipped, "flipped")
    renamed = copy.deepcopy(want)
    renamed.outcomes[0] = "landed"
    with pytest.raises(AssertionError, match="outcomes"):
        compare(want, renamed, "renamed")


def test_the_calibration_and_the_energy_table_fly_as_recorded():
    """The budget unit and the per-action energies, flown alone (one drone, its own arena), are
    the doubles the scalar flight flew before the merge (recorded at commit 609177f)."""
    from cpp_mujoco.physics.action_energy import flown_sequence
    from cpp_mujoco.physics.calibration import calibrate
    from cpp_mujoco.physics.config import PhysicsConfig

    figures = calibrate(PhysicsConfig())
    assert figures["unit_energy_j"] == pytest.approx(488.2464244794845, rel=1e-12)
    assert figures["hover_energy_j"] == pytest.approx(481.75579730840025, rel=1e-12)
    assert figures["move_duration_s"] == pytest.approx(3.000000000000294, rel=1e-12)
    sequence = flown_sequence(PhysicsConfig(wind_speed=9.0, turbulence="moderate"), 3)
    assert [kind for kind, _ in sequence[:4]] == ["upwind", "downwind", "crosswind", "crosswind"]
    recorded = [546.0716673284053, 443.6123116726459, 560.6875390589948, 669.3146182055302]
    assert [j for _, j in sequence[:4]] == pytest.approx(recorded, rel=1e-9)
    assert sequence[-2] == ("hover", pytest.approx(491.2278949545989, rel=1e-9))
