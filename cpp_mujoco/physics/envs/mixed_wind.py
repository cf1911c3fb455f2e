"""Several weathers in one batch: :class:`MixedWindVectorEnv`, for fine-tuning agents in physics.

A :class:`~cpp_mujoco.physics.envs.vector.MuJoCoVectorEnv` flies one :class:`PhysicsConfig`, so
one wind. A wind-robust agent must be fine-tuned on many at once (calm air, and a steady wind
from each compass direction with turbulence) or it forgets the ones it does not see. This env
holds one ``MuJoCoVectorEnv`` per weather ("condition"), each with its share of the slots, and
presents them as ONE gymnasium ``VectorEnv`` in slot order: observations, rewards, flags and
infos (``_key`` masks, and the autoreset ``final_obs`` / ``final_info`` with their masks) are
the sub-envs' arrays concatenated. Slot ``j`` of the mixed env is slot ``j - start`` of its
condition's env, so its episode is the one a plain ``MuJoCo-v0`` with that condition, seed,
options and actions flies (``tests/test_physics_finetune.py``); its ``wind`` observation is
its own condition's wind.

Cost: each batch runs its own control tick, so consecutive conditions that differ only in the
wind's direction fly as one batch (per-drone steady winds, ``MuJoCoVectorEnv(wind_directions=
...)``): calm air and a wind from N/E/S/W are two ticks, not five. Measured on map B (one loaded
core) before that merge: 32 drones in 5 batches flew 16-20 actions/s, the same 32 in one 53-57.

gymnasium's helpers stack single-env samples (``vector.utils.concatenate``) or merge one env's
info at a time (``VectorEnv._add_info``); neither joins batches, so :func:`concat_batches` does.
The spaces are ``vector.utils.batch_space`` of the single env's.
"""

from __future__ import annotations

import dataclasses
import numbers
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium.spaces import MultiDiscrete
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from cpp_mujoco.grid.actions import NUM_ACTIONS
from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.grid.vector_env import restore_generators
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.physics.envs.vector import MuJoCoVectorEnv

# one weather: PhysicsConfig keywords (e.g. wind_speed, wind_direction, turbulence) and slots
Condition = tuple[Mapping[str, Any], int]


def concat_batches(parts: Sequence[Mapping[str, Any]], counts: Sequence[int]) -> dict[str, Any]:
    """Batched dicts (arrays with a leading dimension ``counts[k]``, nested dicts alike) joined
    along the first axis. A key some parts lack (``final_info`` when only some sub-envs ended an
    episode) is filled with zeros there: its ``_key`` mask is then False for those slots."""
    keys = list(dict.fromkeys(k for p in parts for k in p))
    out: dict[str, Any] = {}
    for key in keys:
        template = next(p[key] for p in parts if key in p)
        values = [
            p[key] if key in p else _zeros(template, n) for p, n in zip(parts, counts, strict=True)
        ]
        if isinstance(template, Mapping):
            out[key] = concat_batches(values, counts)
        else:
            out[key] = np.concatenate([np.asarray(v) for v in values])
    return out


def _zeros(template: Any, n: int) -> Any:
    """A stand-in of ``n`` slots for ``template``'s kind (masked out by its ``_key``)."""
    if isinstance(template, Mapping):
        return {k: _zeros(v, n) for k, v in template.items()}
    template = np.asarray(template)
    return np.zeros((n, *template.shape[1:]), dtype=template.dtype)


def _merge_directions(conditions: list[Condition]) -> list[tuple[dict, list[float]]]:
    """Consecutive conditions that differ only in ``wind_direction`` as one batch (the options
    of its first, and one direction per slot): a weather from four directions is one control
    tick, not four (``MuJoCoVectorEnv(wind_directions=...)``)."""
    groups: list[tuple[dict, list[float]]] = []
    for kw, n in conditions:
        rest = {k: v for k, v in kw.items() if k != "wind_direction"}
        direction = float(kw.get("wind_direction", 0.0))
        last = groups[-1] if groups else None
        if last is not None and {k: v for k, v in last[0].items() if k != "wind_direction"} == rest:
            last[1].extend([direction] * int(n))
        else:
            groups.append((dict(kw), [direction] * int(n)))
    return groups


class MixedWindVectorEnv(VectorEnv):
    """One batch of ``MuJoCo-v0`` drones flying several weathers.

    ``conditions``: ``[(physics_kwargs, slots), …]`` in slot order, e.g.
    ``[({}, 6), ({"wind_speed": 9, "wind_direction": 90, "turbulence": "moderate"}, 7), …]``.
    ``map``, ``grid_config``, ``autoreset_mode`` and ``threads`` (MuJoCo threads of each
    sub-env) are shared; ``common`` keywords go to every sub-env under its condition's.

    Seeding as every vector env here: ``reset(seed=s)`` seeds slot j with ``s + j`` (distinct,
    deterministic), ``reset(seed=[s_0, …])`` slot j with ``s_j``. ``options``: ``reset_mask``
    (one bool per slot), ``start`` and ``budget`` as for :class:`MuJoCoVectorEnv` (one value
    for all, or one per reset slot in slot order).
    """

    def __init__(
        self,
        conditions: Sequence[Condition],
        map: str | os.PathLike | GridMap = "A",  # noqa: A002 - the design's keyword
        grid_config: GridConfig | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        threads: int = 1,
        **common: Any,
    ):
        conditions = [(dict(kw), n) for kw, n in conditions]
        if not conditions or any(
            isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 1
            for _, n in conditions
        ):
            raise ValueError(
                "conditions must be a non-empty list of (physics options, slots >= 1), got "
                f"{[n for _, n in conditions]!r} slots"
            )
        grid_map = load_map(map)
        self.envs: list[MuJoCoVectorEnv] = []
        try:
            for kw, directions in _merge_directions(conditions):
                self.envs.append(
                    MuJoCoVectorEnv(
                        len(directions),
                        grid_map,
                        grid_config=grid_config,
                        autoreset_mode=autoreset_mode,
                        threads=threads,
                        wind_directions=directions if "wind_direction" in kw else None,
                        **{**common, **kw},
                    )
                )
        except BaseException:
            for env in self.envs:
                env.close()
            raise
        self.conditions = conditions
        self.counts = [env.num_envs for env in self.envs]
        bounds = np.cumsum([0, *self.counts])
        self.slices = [slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        self.num_envs = int(bounds[-1])
        first = self.envs[0]
        self.grid_map = first.grid_map
        self.autoreset_mode = first.autoreset_mode
        self.render_mode = None
        self.metadata = {"autoreset_mode": self.autoreset_mode, "render_modes": []}
        self.single_observation_space = first.single_observation_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.single_action_space = first.single_action_space
        self.action_space = MultiDiscrete(np.full(self.num_envs, NUM_ACTIONS))

    @classmethod
    def for_training(cls, config: Any, grid_map: GridMap) -> MixedWindVectorEnv:
        """The env of a ``backend="mujoco"`` :class:`~cpp_mujoco.agent.config.TrainConfig`: its
        weathers (``physics_conditions()``), budgets, crash reward and MuJoCo threads, autoreset
        in the same step (as the trainer reads it)."""
        budgets = dataclasses.replace(config.grid_config, wind=None)  # physics sets the costs
        return cls(
            config.physics_conditions(), grid_map, budgets, AutoresetMode.SAME_STEP,
            threads=config.physics_threads,
        )  # fmt: skip

    # ------------------------------------------------------------------ what flies where
    @property
    def physics_configs(self) -> tuple:
        """Each slot's :class:`PhysicsConfig` (its weather), in slot order."""
        return tuple(
            dataclasses.replace(env.physics_config, wind_direction=float(d))
            for env in self.envs
            for d in env.wind_directions
        )

    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:
        """Each slot's generator, in slot order."""
        return tuple(g for env in self.envs for g in env.np_random)

    @property
    def np_random_seed(self) -> tuple[int | None, ...]:
        return tuple(s for env in self.envs for s in env.np_random_seed)

    def _split(self, value: Any, what: str) -> list[Any]:
        """A per-slot sequence (length ``num_envs``) cut into the sub-envs' parts."""
        values = list(value)
        if len(values) != self.num_envs:
            raise ValueError(f"{what} has {len(values)} entries; num_envs is {self.num_envs}")
        return [values[s] for s in self.slices]

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        if seed is None:
            seeds: list[Any] = [None] * len(self.envs)
        elif isinstance(seed, numbers.Integral) and not isinstance(seed, bool):
            seeds = [[int(seed) + j for j in range(s.start, s.stop)] for s in self.slices]
        elif isinstance(seed, (Sequence, np.ndarray)) and not isinstance(seed, (str, bytes)):
            seeds = self._split(seed, "seed list")
        else:
            raise ValueError(
                f"seed must be an int, a list of {self.num_envs} seeds or None, got {seed!r}"
            )
        per_env = self._split_options(options)
        results = [
            env.reset(seed=s, options=o)
            for env, s, o in zip(self.envs, seeds, per_env, strict=True)
        ]
        obs, infos = zip(*results, strict=True)
        return concat_batches(obs, self.counts), concat_batches(infos, self.counts)

    def _split_options(self, options: dict[str, Any] | None) -> list[dict[str, Any] | None]:
        """``reset_mask`` cut per sub-env; per-reset-slot ``start`` / ``budget`` arrays too."""
        if options is None:
            return [None] * len(self.envs)
        if not isinstance(options, Mapping):
            raise ValueError(f"reset options must be a dict, got {options!r}")
        mask = options.get("reset_mask")
        if mask is None:
            mask = np.ones(self.num_envs, dtype=bool)
        parts = [np.asarray(m, dtype=bool) for m in self._split(np.asarray(mask), "reset_mask")]
        chosen = np.cumsum([0, *(int(m.sum()) for m in parts)])
        out = [dict(options) for _ in self.envs]
        if "reset_mask" in options:
            for o, m in zip(out, parts, strict=True):
                o["reset_mask"] = m
        for key, item_ndim in (("start", 1), ("budget", 0)):
            value = options.get(key)
            if value is None or np.ndim(value) == item_ndim:
                continue  # absent, or one value for every slot
            value = np.asarray(value)
            if len(value) != chosen[-1]:
                raise ValueError(f"{key} has {len(value)} entries for {chosen[-1]} reset slots")
            for k, o in enumerate(out):
                o[key] = value[chosen[k] : chosen[k + 1]]
        for o, m in zip(
            out, parts, strict=True
        ):  # a sub-env none of whose slots reset: nothing to give it
            if not m.any():
                o.pop("start", None)
                o.pop("budget", None)
        return out

    def step(self, actions: Any):
        actions = np.asarray(actions)
        if not np.issubdtype(actions.dtype, np.integer) or actions.size != self.num_envs:
            raise ValueError(
                f"actions must be {self.num_envs} integers in 0..{NUM_ACTIONS - 1}, got {actions!r}"
            )
        actions = actions.reshape(self.num_envs)
        results = [env.step(actions[s]) for env, s in zip(self.envs, self.slices, strict=True)]
        obs, reward, terminated, truncated, infos = zip(*results, strict=True)
        return (
            concat_batches(obs, self.counts),
            np.concatenate(reward),
            np.concatenate(terminated),
            np.concatenate(truncated),
            concat_batches(infos, self.counts),
        )

    def close_extras(self, **kwargs: Any) -> None:
        for env in self.envs:
            env.close(**kwargs)

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict[str, Any]:
        """Each slot's generator state. A MuJoCo episode in flight is not saved (its state is
        MuJoCo's and the controllers'): after :meth:`load_state_dict`, :meth:`reset` without a
        seed starts fresh episodes, drawn from the restored generators."""
        return {"rng": [g.bit_generator.state for g in self.np_random]}

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore the slots' generators (``ValueError`` if they do not fit); then :meth:`reset`."""
        states = state.get("rng") if isinstance(state, Mapping) else None
        rngs = restore_generators(states, self.num_envs)
        for env, s in zip(self.envs, self.slices, strict=True):
            env._rngs = rngs[s]  # the grid vector env's own generators (GridVectorEnv.np_random)
