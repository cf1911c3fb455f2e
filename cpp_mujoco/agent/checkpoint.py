"""Checkpoint files: written atomically, read with ``torch.load(weights_only=True)`` only.

Two kinds share one layout:

* **agent** (``kind = "cpp_mujoco.agent"``): network weights (fp32), the network's shape and the
  budget input scale, the training config and metrics — the bundled ``A.pt``, ``B.pt``, ``C.pt``.
* **training state** (``kind = "cpp_mujoco.train_state"``): the agent part plus everything needed to
  continue a run exactly (:class:`~cpp_mujoco.agent.training_state.TrainingState`).

Either kind holds the paper's per-map network (no ``architecture`` key, as every file before the
general agent) or a size-independent one: ``architecture = "general"`` the global-local
:class:`~cpp_mujoco.agent.general_network.GeneralQNetwork`, ``"general-fcn"`` the fully
convolutional :class:`~cpp_mujoco.agent.fcn_network.FCNQNetwork` (:data:`GENERAL_NETWORKS`), whose
``network_kwargs`` are their layer sizes instead of a map size; :func:`network_from_checkpoint`
rebuilds each.

Anything else (a folder, another file type, a truncated file, a different map size, NaN/inf
weights, a non-positive budget scale) raises :class:`CheckpointError` with a message that names the
file and says what is wrong. Writes go through :mod:`cpp_mujoco.util.io` (atomic; a full disk is a
one-line ``WriteError`` and the previous file is untouched).
"""

from __future__ import annotations

import io
import math
import os
import pickle
import zipfile
from collections.abc import Sequence
from pathlib import Path

import torch

from cpp_mujoco.agent.fcn_network import ARCHITECTURE as FCN
from cpp_mujoco.agent.fcn_network import FCNQNetwork, check_fcn_kwargs
from cpp_mujoco.agent.general_network import ARCHITECTURE as GENERAL
from cpp_mujoco.agent.general_network import GeneralQNetwork, check_general_kwargs
from cpp_mujoco.agent.network import QNetwork
from cpp_mujoco.maps import MAX_SIDE
from cpp_mujoco.util.io import atomic_write_bytes

FORMAT_VERSION = 1
AGENT_KIND = "cpp_mujoco.agent"
TRAIN_KIND = "cpp_mujoco.train_state"
KINDS = (AGENT_KIND, TRAIN_KIND)
# the size-independent networks: a checkpoint's "architecture" → (class, network_kwargs check)
GENERAL_NETWORKS = {
    GENERAL: (GeneralQNetwork, check_general_kwargs),
    FCN: (FCNQNetwork, check_fcn_kwargs),
}


class CheckpointError(ValueError):
    """A file that is not a usable cpp_mujoco checkpoint; the message says why."""


def atomic_save(obj: dict, path: str | os.PathLike) -> Path:
    """Serialise in memory, then write atomically (:mod:`cpp_mujoco.util.io`): a crash or a full
    disk
    never leaves half a file or a temporary one, and the previous file stays as it was.

    ``torch.save`` to a file reports a failed write as "unexpected pos …"; writing the bytes
    ourselves gives the operating system's reason (no space left, file too large).
    """
    buffer = io.BytesIO()
    torch.save(obj, buffer)
    return atomic_write_bytes(path, buffer.getbuffer())


def _detail(exc: BaseException) -> str:
    """torch's first line, unless it advises disabling weights_only (never safe here)."""
    text = (str(exc).strip().splitlines() or [""])[0][:200]
    if "weights_only" in text or not text:
        return type(exc).__name__
    return f"{type(exc).__name__}: {text}"


def _read(path: Path) -> dict:
    if path.is_dir():
        raise CheckpointError(f"{path} is a folder, not a checkpoint file")
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
            reason = "holds objects other than tensors and plain data (not a cpp_mujoco checkpoint)"
        else:
            reason = f"truncated or corrupt ({_detail(exc)})"
        raise CheckpointError(f"cannot read checkpoint {path}: {reason}") from None
    if not isinstance(obj, dict) or obj.get("kind") not in KINDS:
        raise CheckpointError(
            f"{path} is a torch file but not a cpp_mujoco checkpoint (no 'kind' in {KINDS})"
        )
    return obj


def _check_weights(path: Path, what: str, weights: object) -> None:
    """Every tensor present and finite: NaN weights would act (argmax of NaN) without a sound."""
    if not isinstance(weights, dict) or not weights:
        raise CheckpointError(f"{path}: {what} holds no weights")
    for name, value in weights.items():
        if not isinstance(value, torch.Tensor):
            raise CheckpointError(f"{path}: {what} entry {name!r} is not a tensor")
        if value.is_floating_point() and not bool(torch.isfinite(value).all()):
            bad = int((~torch.isfinite(value)).sum())
            raise CheckpointError(
                f"{path}: {what} weight {name!r} has {bad} NaN/inf value(s) of {value.numel()} "
                "(the run diverged or the file is damaged)"
            )


def _check(path: Path, obj: dict) -> None:
    version = obj.get("format_version")
    if version != FORMAT_VERSION:
        raise CheckpointError(
            f"{path} has checkpoint format {version!r}; this version reads {FORMAT_VERSION}"
        )
    for key in ("network", "network_kwargs", "budget_scale"):
        if key not in obj:
            raise CheckpointError(f"{path} lacks {key!r}; the file is incomplete")
    kw = obj["network_kwargs"]
    architecture = obj.get("architecture", "paper")  # files without one hold the paper's net
    if is_general(obj):
        problem = GENERAL_NETWORKS[architecture][1](kw)
        if problem:
            raise CheckpointError(f"{path}: {problem}")
    elif architecture != "paper":
        known = ", ".join(["paper", *GENERAL_NETWORKS])
        raise CheckpointError(
            f"{path}: unknown network architecture {architecture!r} (known: {known})"
        )
    elif (
        not isinstance(kw, dict)
        or not {"height", "width"} <= set(kw) <= {"height", "width", "wind_inputs"}
        or not all(type(kw[k]) is int and 1 <= kw[k] <= MAX_SIDE for k in ("height", "width"))
        or type(kw.get("wind_inputs", False)) is not bool
    ):
        raise CheckpointError(
            f"{path}: network_kwargs {kw!r} are not a map size (height and width in "
            f"1..{MAX_SIDE}) and an optional wind_inputs flag"
        )
    scale = obj["budget_scale"]
    if type(scale) not in (int, float) or not math.isfinite(scale) or scale <= 0:
        raise CheckpointError(f"{path}: budget_scale {scale!r} is not a positive number")
    _check_weights(path, "network", obj["network"])
    if obj["kind"] == TRAIN_KIND:
        _check_weights(path, "target network", obj.get("target"))
        if not isinstance(obj.get("config"), dict):
            raise CheckpointError(f"{path}: training checkpoint without its config")


def load_checkpoint(path: str | os.PathLike, *, map_shape: tuple[int, int] | None = None) -> dict:
    """Read and validate a checkpoint; ``map_shape`` (H, W), if given, must match the network's
    (a general network flies any size).

    Raises :class:`CheckpointError` naming the file and what is wrong: not a file, not ours,
    truncated, another format version, non-finite weights, a bad budget scale or map size.
    """
    path = Path(path)
    obj = _read(path)
    _check(path, obj)
    if map_shape is not None and not is_general(obj):  # a general network: any size
        kw = obj["network_kwargs"]
        got = (kw["height"], kw["width"])
        if got != tuple(map_shape):
            raise CheckpointError(
                f"{path} holds a network for {got[0]}x{got[1]} maps (map {obj.get('map')!r}), "
                f"but this map is {map_shape[0]}x{map_shape[1]}"
            )
    return obj


def is_general(obj: dict) -> bool:
    """Whether a checkpoint holds a size-independent network (:data:`GENERAL_NETWORKS`)."""
    architecture = obj.get("architecture")
    return isinstance(architecture, str) and architecture in GENERAL_NETWORKS


def network_from_checkpoint(
    obj: dict, source: str = "checkpoint"
) -> QNetwork | GeneralQNetwork | FCNQNetwork:
    """The network a checkpoint describes: the paper's, or a general one (``architecture``)."""
    kind = GENERAL_NETWORKS[obj["architecture"]][0] if is_general(obj) else QNetwork
    try:
        net = kind(**obj["network_kwargs"])
        net.load_state_dict(obj["network"])
    except (TypeError, ValueError, RuntimeError, KeyError) as exc:
        raise CheckpointError(
            f"{source}: network weights do not fit the stored shape ({str(exc)[:200]})"
        ) from None
    return net


def agent_payload(
    network: QNetwork | GeneralQNetwork | FCNQNetwork,
    *,
    budget_scale: float,
    map_name: str,
    config: dict,
    metrics: dict | None = None,
    map_digest: str = "",
    rules: Sequence[str] = (),
) -> dict:
    """The agent part of a checkpoint (everything ``load_agent`` needs; fp32 weights only).

    ``map_digest`` (:attr:`GridMap.digest`) fingerprints the training map's cells, so a resume
    on an edited map file of the same name is refused instead of silently continuing. A general
    network's payload says so (``architecture``) and holds its shape's arguments. ``rules``: the
    names of the rules the agent acts with (:mod:`~cpp_mujoco.agent.rules`), in order.
    """
    general = {cls: name for name, (cls, _) in GENERAL_NETWORKS.items()}
    if type(network) in general:
        shape = {"architecture": general[type(network)], "network_kwargs": dict(network.kwargs)}
    else:  # the paper's: the same keys as before the general network existed
        shape = {
            "network_kwargs": {
                "height": network.height,
                "width": network.width,
                **({"wind_inputs": True} if network.wind_inputs else {}),
            }
        }
    return {
        "kind": AGENT_KIND,
        "format_version": FORMAT_VERSION,
        "network": {
            k: v.detach().to("cpu", torch.float32).clone() for k, v in network.state_dict().items()
        },
        **shape,
        "budget_scale": float(budget_scale),
        "map": map_name,
        "map_digest": map_digest,
        "config": dict(config),
        "metrics": dict(metrics or {}),
        "rules": list(rules),
    }
