"""The full grid protocol of each bundled paper agent, recorded episode by episode.

Why: flying map A's whole protocol (36 landing cells × 51 budgets) with the 1.19 M-parameter
network takes half a minute on one CPU thread. ``tests/test_agent_bundled.py`` checks the bar on
this record and re-flies a fifth of it (every 5th budget, every landing cell), which must give the
recorded episodes: a change to the agent, its observations, the MDP or the protocol shows there.
The record names the agent file's and the map's digests, so a retrained agent or an edited map is
refused until it is recorded again.

Record again (only when a change of the agents' flights is intended) with::

    python -m tests.bundled_protocol
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from cpp_mujoco.agent import GENERAL_AGENTS, bundled_agents, load_agent
from cpp_mujoco.protocol.evaluate import evaluate
from cpp_mujoco.util.io import atomic_write_bytes

PATH = Path(__file__).parent / "fixtures" / "bundled_protocol.npz"
RECORD = "python -m tests.bundled_protocol"
FIELDS = ("budgets", "landed", "coverage", "steps")
NAMES = [n for n in bundled_agents() if not n.endswith("-wind") and n not in GENERAL_AGENTS]


def record() -> None:
    arrays = {}
    for name in NAMES:
        agent = load_agent(name)
        result = evaluate(agent, name)
        arrays[f"{name}/agent_digest"] = np.array(agent.metadata["digest"])
        arrays[f"{name}/map_digest"] = np.array(result.grid_map.digest)
        for key in FIELDS:
            arrays[f"{name}/{key}"] = getattr(result, key)
        print(f"{name}: {result.landed.size} episodes, landing {result.landing_ratio:.4f}, "
              f"coverage {result.coverage_ratio:.4f}")  # fmt: skip
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    atomic_write_bytes(PATH, buffer.getvalue())


def load(name: str) -> dict[str, np.ndarray]:
    """The recorded protocol of the bundled agent ``name``."""
    with np.load(PATH) as data:
        return {k.split("/", 1)[1]: data[k] for k in data.files if k.startswith(f"{name}/")}


if __name__ == "__main__":
    record()
