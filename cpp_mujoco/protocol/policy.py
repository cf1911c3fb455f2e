"""The policy protocol every evaluation loop speaks.

A policy maps a batch of observations (a dict of arrays with leading dimension N) to N actions.
Policies that keep state between calls (a planner's plans, a random stream, a recurrent network's
memory) also need to know where episodes begin: the episode loops
(:mod:`cpp_mujoco.protocol.episode`)
call :func:`start_episodes` first, which calls the policy's ``reset(num_episodes, seed)`` if it
has one. Without it a planner reused for a second protocol, or for the next episode of a worker
that flies one episode at a time, would follow its previous plan. One env's observation reaches
the batched ``act`` as a batch of one through :func:`as_batch` / :func:`act_one`.

:class:`SB3Policy` runs any object with Stable-Baselines3's ``predict`` through the same loops;
:func:`as_policy` picks the adapter for an object.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np

Observation = dict[str, np.ndarray]


@runtime_checkable
class Policy(Protocol):
    """Anything with a batched ``act``; ``reset(num_episodes, seed)`` is optional."""

    def act(self, obs: Observation) -> np.ndarray:
        """Actions (N,) for a batch of observations with leading dimension N."""


class MapMismatchError(ValueError):
    """A policy flown on a map it was not made for (e.g. an agent trained on another map)."""


def check_fits(policy: Any, grid_map: Any, any_map: bool = False) -> str | None:
    """Refuse a policy that says it does not fit ``grid_map``: a policy may offer
    ``fits(grid_map)``, returning why it does not (None: it does). :class:`MapMismatchError`
    naming both maps, unless ``any_map``; then the reason is returned, for results to record."""
    fits = getattr(policy, "fits", None)
    reason = fits(grid_map) if callable(fits) else None
    if reason and not any_map:
        raise MapMismatchError(f"{reason}; pass any_map=True (--any-map) to fly it there anyway")
    return reason or None


def check_view(policy: Any, fov_side: int) -> None:
    """Refuse a policy that plans with another camera square than the episodes fly (a planner's
    ``fov_side``): its plans would be for cells it does not see, or miss cells it does."""
    planned = getattr(policy, "fov_side", fov_side)
    if planned != fov_side:
        raise ValueError(
            f"policy plans with a {planned}x{planned} view, the episodes see "
            f"{fov_side}x{fov_side} (make_planner(..., fov_side=...))"
        )


def start_episodes(policy: Any, num_episodes: int, seed: int | None = None) -> None:
    """Tell ``policy`` that ``num_episodes`` new episodes start (the batch of its next ``act``).

    ``seed`` names the batch within a run (a chunk index, a physics episode index), so a
    stochastic policy can reseed and a protocol run twice gives the same results. Policies
    without ``reset`` (stateless planners, plain callables) are left alone.
    """
    reset = getattr(policy, "reset", None)
    if callable(reset):
        reset(int(num_episodes), seed)


def act_batch(policy: Any, obs: Observation, active: np.ndarray) -> np.ndarray:
    """The actions of ``policy`` for a batch whose rows ``active`` marks are still flying.

    A policy may offer ``act_active(obs, active)``: the same actions as ``act`` for the active
    rows, anything for the others (the loops give them a landing their env ignores) — a
    network reads only the active rows. Without it, ``act``."""
    act_active = getattr(policy, "act_active", None)
    return act_active(obs, active) if callable(act_active) else policy.act(obs)


def as_batch(obs: Observation) -> Observation:
    """One env's observation as a batch of one (leading dimension 1): what ``act`` takes."""
    return {k: np.asarray(v)[None] for k, v in obs.items()}


def act_one(policy: Any, obs: Observation) -> int:
    """The action of ``policy`` for one env's observation, through its batched ``act``."""
    actions = np.asarray(policy.act(as_batch(obs))).reshape(-1)
    if actions.size != 1:  # never take the first of several actions for one observation
        raise ValueError(f"policy gave {actions.size} actions for one observation")
    return int(actions[0])


def batched_for_sb3(obs: Observation) -> Observation:
    """Our batched observation as SB3's ``predict`` expects it: writable, contiguous arrays with
    the batch as leading dimension (the grid MDP hands out ``map`` as a read-only broadcast)."""
    n = np.shape(obs["coverage"])[0]
    out = {k: np.array(v) for k, v in obs.items()}  # np.array copies: contiguous and writable
    for key, cells in (("map", 3), ("obstacle", 2)):  # one map for the whole batch
        if key in out and out[key].ndim == cells:
            out[key] = np.repeat(out[key][None], n, axis=0)
    return out


class SB3Policy:
    """A policy from any object with SB3's ``predict(obs, state, episode_start, deterministic)``
    (``DQN``, ``PPO``, their ``.policy``, sb3-contrib's recurrent models).

    Recurrent state is carried between calls and restarted by :meth:`reset`. Pickled for worker
    processes, a model is reduced to its ``policy`` network (no replay buffer, no env).
    """

    def __init__(self, model: Any, deterministic: bool = True, name: str | None = None):
        if not callable(getattr(model, "predict", None)):
            raise TypeError(f"{type(model).__name__} has no predict(); not an SB3 model")
        self.model = model
        self.deterministic = deterministic
        self.name = name or f"sb3-{type(model).__name__.lower()}"
        self._state: Any = None
        self._episode_start: np.ndarray | None = None

    def reset(self, num_episodes: int, seed: int | None = None) -> None:
        self._state = None
        self._episode_start = np.ones(num_episodes, dtype=bool)

    def act(self, obs: Observation) -> np.ndarray:
        batch = batched_for_sb3(obs)
        n = batch["coverage"].shape[0]
        if self._episode_start is None or self._episode_start.size != n:
            self.reset(n)
        actions, self._state = self.model.predict(
            batch,
            state=self._state,
            episode_start=self._episode_start,
            deterministic=self.deterministic,
        )
        self._episode_start = np.zeros(n, dtype=bool)
        return np.asarray(actions, dtype=np.int64).reshape(n)

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        inner = getattr(self.model, "policy", None)
        if callable(getattr(inner, "predict", None)):
            state["model"] = inner
        return state


class _CallablePolicy:
    """A plain function ``obs -> actions`` as a policy."""

    def __init__(self, fn: Callable[[Observation], Any]):
        self.fn = fn
        self.name = getattr(fn, "__name__", type(fn).__name__)

    def act(self, obs: Observation) -> np.ndarray:
        return np.asarray(self.fn(obs))


def as_policy(obj: Any) -> Any:
    """``obj`` itself if it has ``act``; an :class:`SB3Policy` if it has SB3's ``predict``; a
    wrapper for a plain callable. Anything else is a ``TypeError`` naming what is missing."""
    if callable(getattr(obj, "act", None)):
        return obj
    if callable(getattr(obj, "predict", None)):
        return SB3Policy(obj)
    if callable(obj):
        return _CallablePolicy(obj)
    raise TypeError(
        f"{type(obj).__name__} is not a policy: it needs act(obs) -> actions, SB3's predict(), "
        "or to be callable"
    )


def policy_name(policy: object) -> str:
    """How results name a policy: its ``name`` attribute, else its class name."""
    return str(getattr(policy, "name", type(policy).__name__))


def policy_identity(policy: object) -> dict[str, Any]:
    """What results record of a policy beyond its name: the file a trained agent was loaded
    from, its digest and architecture (its ``metadata``), then whatever the policy says of
    itself through ``identity()`` — a planner its solver and limits, an agent its network and
    the rules it acts with — so two files of one name, or one file with and without a rule,
    are never read alike."""
    meta = getattr(policy, "metadata", None) or {}
    out = {k: meta[k] for k in ("source", "digest", "bundled", "architecture") if k in meta}
    if callable(own := getattr(policy, "identity", None)):
        out.update(own())
    return out
