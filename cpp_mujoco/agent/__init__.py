"""The paper's DDQN agent: network, training, checkpoints and the bundled agents for maps A, B, C.

``load_agent("A")`` loads the bundled agent for map A; ``load_agent(path)`` any agent or training
checkpoint. The result acts greedily: ``agent.act(obs) -> int`` for one observation,
``np.ndarray`` for a batch.
"""

from __future__ import annotations

import os
from pathlib import Path

from cpp_mujoco.agent.checkpoint import CheckpointError, load_checkpoint, network_from_checkpoint
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.network import QNetwork
from cpp_mujoco.agent.policy import GreedyAgent, MapSizeError

BUNDLED_DIR = Path(__file__).resolve().parent / "bundled"


def bundled_agents() -> list[str]:
    """Names of the bundled agents (one per bundled map)."""
    return sorted(p.stem for p in BUNDLED_DIR.glob("*.pt"))


def load_agent(name_or_path: str | os.PathLike, device: str = "cpu") -> GreedyAgent:
    """A bundled agent by map name (``"A"``, ``"B"``, ``"C"``), or an agent/training checkpoint."""
    text = os.fspath(name_or_path)
    bundled = BUNDLED_DIR / f"{text}.pt"
    if not any(sep in text for sep in ("/", os.sep)) and not text.endswith(".pt"):
        if not bundled.is_file():
            raise CheckpointError(
                f"no bundled agent {text!r}; bundled: {', '.join(bundled_agents()) or 'none'}"
            )
        path = bundled
    else:
        path = Path(text)
    obj = load_checkpoint(path)
    net = network_from_checkpoint(obj, str(path))
    return GreedyAgent(
        net,
        obj["budget_scale"],
        device,
        name=f"ddqn-{obj.get('map', path.stem)}",
        metadata={k: obj.get(k) for k in ("map", "config", "metrics")},
    )


__all__ = [
    "BUNDLED_DIR",
    "CheckpointError",
    "GreedyAgent",
    "MapSizeError",
    "QNetwork",
    "TrainConfig",
    "bundled_agents",
    "load_agent",
]
