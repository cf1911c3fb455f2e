"""The package a user installs: the wheel carries the bundled maps, assets, agents and the
optimum's answers, and its command runs from anywhere, without the checkout."""

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """The wheel built from this checkout, unpacked as pip installs it (a folder on sys.path)."""
    pytest.importorskip("hatchling", reason="building the wheel needs hatchling (dev extra)")
    dist = tmp_path_factory.mktemp("dist")
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
         "-w", str(dist), str(ROOT)],
        check=True, capture_output=True, timeout=300,
    )  # fmt: skip
    (wheel,) = dist.glob("cpp_mujoco-*.whl")
    site = tmp_path_factory.mktemp("site")
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        z.extractall(site)
    return site, names


def _run(site: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess:
    # the unpacked wheel ahead of this checkout's editable install, run from a bare folder
    env = {**os.environ, "PYTHONPATH": str(site), "PYTHONDONTWRITEBYTECODE": "1"}
    return subprocess.run(
        [sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=600
    )


def test_the_wheel_holds_the_bundled_data(installed):
    _, names = installed
    for name in ("maps/A.png", "assets/quadrotor.xml", "optimum/"):
        assert any(n.startswith(f"cpp_mujoco/_bundled/{name}") for n in names), name
    assert {"cpp_mujoco/agent/bundled/A.pt", "cpp_mujoco/agent/bundled/general.pt"} <= set(names)
    assert not any(n.startswith(("tests/", "scripts/", "docs/")) for n in names)


def test_the_installed_command_runs_outside_the_checkout(installed, tmp_path):
    site, _ = installed
    where = _run(site, tmp_path, "-c", "import cpp_mujoco; print(cpp_mujoco.__file__)")
    assert where.stdout.startswith(str(site)), where.stderr
    version = _run(site, tmp_path, "-m", "cpp_mujoco", "--version")
    assert version.returncode == 0 and version.stdout.startswith("cpp-mujoco ")
    argv = ["evaluate", "--map", "A", "--agent", "A", "--budget-step", "25", "--out", "out"]
    run = _run(site, tmp_path, "-m", "cpp_mujoco", *argv, "--no-progress")
    assert run.returncode == 0, run.stderr
    (path,) = [p for p in (tmp_path / "out").glob("grid_A_*.json") if "tables" not in p.name]
    result = json.loads(path.read_text())
    assert result["landing_ratio"] == 1.0
    # the optimum beside the agent, from the answers the wheel carries
    assert result["optimum"]["episodes_known"] == result["episodes"]
