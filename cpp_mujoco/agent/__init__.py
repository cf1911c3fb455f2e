"""The paper's DDQN agent: network, training, checkpoints and the bundled agents for maps A, B, C.

``load_agent("A")`` loads the bundled agent for map A; ``load_agent(path)`` any agent or training
checkpoint — a per-map agent or a general one (:mod:`cpp_mujoco.agent.general_network`, trained by
``cpp-mujoco train-general`` on generated maps, flies maps of any size); ``load_agent("general")``
the bundled general agent (``scripts/train_general.py``; it acts with the return mask). The result
acts greedily: ``agent.act(obs) -> int`` for one observation, ``np.ndarray`` for a batch.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from cpp_mujoco.agent.checkpoint import CheckpointError, load_checkpoint, network_from_checkpoint
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.network import QNetwork
from cpp_mujoco.agent.policy import GreedyAgent, MapSizeError
from cpp_mujoco.agent.rules import make_rules, rule_metadata, rule_names_of
from cpp_mujoco.agent.rules.symmetric_q import own_orientation_maps
from cpp_mujoco.grid.way_home import ReturnMargin
from cpp_mujoco.maps import bundled_maps, load_map
from cpp_mujoco.util.io import resolve_named_file

BUNDLED_DIR = Path(__file__).resolve().parent / "bundled"
GENERAL_AGENT = "general"  # bundled/general.pt: the general agent (scripts/train_general.py)
# bundled/general-wind.pt: the general agent fine-tuned in the grid's wind option (stage 4)
GENERAL_WIND_AGENT = "general-wind"
# bundled/general-city.pt: the general agent fine-tuned on city maps, reading their obstacles
GENERAL_CITY_AGENT = "general-city"
# they fly any map; the rest one map each
GENERAL_AGENTS = (GENERAL_AGENT, GENERAL_WIND_AGENT, GENERAL_CITY_AGENT)


def bundled_agents() -> list[str]:
    """Names of the bundled agents: the paper's agent of each bundled map (``A``) and its
    wind-robust agent (``A-wind``, trained in the grid's wind option)."""
    return sorted(p.stem for p in BUNDLED_DIR.glob("*.pt"))


def load_agent(name_or_path: str | os.PathLike, device: str = "cpu") -> GreedyAgent:
    """A bundled agent by name (``"A"``, ``"B"``, ``"C"``, ``"A-wind"`` …), or an agent/training
    checkpoint.

    The agent's ``name`` says which: ``ddqn-A`` is the bundled agent, ``ddqn-A (file)`` a user's
    ``A.pt``; ``metadata`` carries ``source`` (the file), ``bundled`` and the file's ``digest``.
    """
    if os.fspath(name_or_path) == GENERAL_AGENT and not (BUNDLED_DIR / "general.pt").is_file():
        raise CheckpointError(
            f"no general agent is bundled yet ({BUNDLED_DIR / 'general.pt'} does not exist): "
            "train one with `cpp-mujoco train-general --out DIR` and load DIR/best.pt"
        )
    where = resolve_named_file(
        name_or_path, bundled=BUNDLED_DIR, suffix=".pt", kind="agent", error=CheckpointError
    )
    obj = load_checkpoint(where.path)
    net = network_from_checkpoint(obj, str(where.path))
    # the rules it acts with: the file's list, or (files from before the list) its config's
    # booleans; the return mask in wind keeps the margin of the wind planners it learned from
    try:
        names = rule_names_of(obj)
    except ValueError as e:
        raise CheckpointError(f"{where.path}: {e}") from None
    wind_margin = _wind_margin((obj.get("config") or {}).get("wind_planner_sigmas"), where.path)
    metadata = {
        **{k: obj.get(k) for k in ("map", "config", "metrics")},
        "map_digest": _trained_digest(obj),
        **{k: obj[k] for k in ("train_maps", "validation_maps") if k in obj},  # general
        "architecture": obj.get("architecture", "paper"),
        **rule_metadata(names),
        "source": str(where.path),
        "bundled": where.bundled,
        "digest": hashlib.sha256(where.path.read_bytes()).hexdigest()[:12],
    }
    return GreedyAgent(
        net,
        obj["budget_scale"],
        device,
        name=f"ddqn-{where.name}" if where.bundled else f"ddqn-{where.name} (file)",
        metadata=metadata,
        rules=make_rules(names, wind_margin, own_orientation_maps(metadata)),
    )


def _trained_digest(obj: dict) -> str | None:
    """The cells the agent was trained on: its file's ``map_digest``; a file from before the
    digest names a bundled map, whose digest it is; None when unknown (a general agent)."""
    if obj.get("map_digest"):
        return obj["map_digest"]
    name = obj.get("map")
    if isinstance(name, str) and name in bundled_maps():
        return load_map(name).digest
    return None


def _wind_margin(sigmas, path) -> ReturnMargin | None:
    """The margin a masked agent's wind planners kept (its config's ``wind_planner_sigmas``),
    which its return rule keeps in wind; None for a file without one."""
    if sigmas is None:
        return None
    if isinstance(sigmas, bool) or not isinstance(sigmas, (int, float)) or not 0 <= sigmas < 100:
        raise CheckpointError(f"{path}: config wind_planner_sigmas {sigmas!r} is not a margin")
    return ReturnMargin(gusty_sigmas=float(sigmas))


__all__ = [
    "BUNDLED_DIR",
    "CheckpointError",
    "GENERAL_AGENT",
    "GENERAL_AGENTS",
    "GENERAL_CITY_AGENT",
    "GENERAL_WIND_AGENT",
    "GreedyAgent",
    "MapSizeError",
    "QNetwork",
    "TrainConfig",
    "bundled_agents",
    "load_agent",
]
