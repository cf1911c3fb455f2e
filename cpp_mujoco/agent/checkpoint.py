"""Checkpoint files: written atomically, read with ``torch.load(weights_only=True)`` only.

Two kinds share one layout:

* **agent** (``kind = "cpp_mujoco.agent"``): network weights (fp32), the network's shape and the
  budget input scale, the training config and metrics — the bundled ``A.pt``, ``B.pt``, ``C.pt``.
* **training state** (``kind = "cpp_mujoco.train_state"``): the agent part plus everything needed to
  continue a run exactly — target network, optimiser, replay memory, environment state, RNG
  states, counters and the evaluation history.

Anything else (another file type, a truncated file, a different map size) raises
:class:`CheckpointError` with a message that says what is wrong.
"""

from __future__ import annotations

import io
import os
import pickle
import zipfile
from pathlib import Path

import torch

from cpp_mujoco.agent.network import QNetwork

FORMAT_VERSION = 1
AGENT_KIND = "cpp_mujoco.agent"
TRAIN_KIND = "cpp_mujoco.train_state"
KINDS = (AGENT_KIND, TRAIN_KIND)


class CheckpointError(ValueError):
    """A file that is not a usable cpp_mujoco checkpoint; the message says why."""


def atomic_save(obj: dict, path: str | os.PathLike) -> Path:
    """``torch.save`` to ``path.tmp``, fsync, ``os.replace``: a crash never leaves half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        torch.save(obj, f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return path


def load_checkpoint(path: str | os.PathLike, *, map_shape: tuple[int, int] | None = None) -> dict:
    """Read and validate a checkpoint; ``map_shape`` (H, W), if given, must match the network's."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} does not exist")
    data = path.read_bytes()
    try:
        obj = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except (
        RuntimeError,
        pickle.UnpicklingError,
        EOFError,
        zipfile.BadZipFile,
        ValueError,
        KeyError,
        OSError,
    ) as exc:
        if data[:2] != b"PK":
            reason = "not a torch checkpoint"
        elif isinstance(exc, pickle.UnpicklingError):
            reason = "holds objects a weights-only load refuses (not a cpp_mujoco checkpoint)"
        else:
            reason = "truncated or corrupt"
        raise CheckpointError(
            f"cannot read checkpoint {path}: {reason} ({type(exc).__name__}: {str(exc)[:200]})"
        ) from None
    if not isinstance(obj, dict) or obj.get("kind") not in KINDS:
        raise CheckpointError(
            f"{path} is a torch file but not a cpp_mujoco checkpoint (no 'kind' in {KINDS})"
        )
    version = obj.get("format_version")
    if version != FORMAT_VERSION:
        raise CheckpointError(
            f"{path} has checkpoint format {version!r}; this version reads {FORMAT_VERSION}"
        )
    for key in ("network", "network_kwargs", "budget_scale"):
        if key not in obj:
            raise CheckpointError(f"{path} lacks {key!r}; the file is incomplete")
    if map_shape is not None:
        kw = obj["network_kwargs"]
        got = (int(kw["height"]), int(kw["width"]))
        if got != tuple(map_shape):
            raise CheckpointError(
                f"{path} holds a network for {got[0]}x{got[1]} maps (map {obj.get('map')!r}), "
                f"but this map is {map_shape[0]}x{map_shape[1]}"
            )
    return obj


def network_from_checkpoint(obj: dict, source: str = "checkpoint") -> QNetwork:
    try:
        net = QNetwork(**obj["network_kwargs"])
        net.load_state_dict(obj["network"])
    except (TypeError, RuntimeError, KeyError) as exc:
        raise CheckpointError(
            f"{source}: network weights do not fit the stored shape ({str(exc)[:200]})"
        ) from None
    return net


def agent_payload(
    network: QNetwork,
    *,
    budget_scale: float,
    map_name: str,
    config: dict,
    metrics: dict | None = None,
) -> dict:
    """The agent part of a checkpoint (everything ``load_agent`` needs; fp32 weights only)."""
    return {
        "kind": AGENT_KIND,
        "format_version": FORMAT_VERSION,
        "network": {
            k: v.detach().to("cpu", torch.float32).clone() for k, v in network.state_dict().items()
        },
        "network_kwargs": {"height": network.height, "width": network.width},
        "budget_scale": float(budget_scale),
        "map": map_name,
        "config": dict(config),
        "metrics": dict(metrics or {}),
    }
