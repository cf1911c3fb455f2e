"""The native batched env: ``gymnasium.make_vec("cpp_mujoco/Grid-v0", num_envs=N, map=...)``.

All N environments live in one :class:`GridMDP`; a step is a handful of array operations, not N
Python calls. Gymnasium's vector API: infos are dicts of arrays with ``_key`` masks.

Seeding follows :class:`gymnasium.vector.SyncVectorEnv`: each env has its own generator,
``reset(seed=s)`` seeds env i with ``s + i``, ``reset(seed=[s0, …])`` env i with ``s_i`` (``None``
keeps its generator), and every reset of env i draws its start and budget from env i's generator
exactly as a single ``Grid-v0`` would. So N single envs seeded s_i and this env seeded [s_i] see
the same episodes (``tests/test_gym_citizen.py``).
"""

from __future__ import annotations

import numbers
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium.spaces import MultiDiscrete
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from cpp_mujoco.grid.actions import NUM_ACTIONS
from cpp_mujoco.grid.image import grid_image
from cpp_mujoco.grid.mdp import GridConfig, GridMDP
from cpp_mujoco.grid.spaces import (
    RENDER_MODES,
    action_space,
    check_render_mode,
    observation_space,
    reset_options,
)
from cpp_mujoco.maps import GridMap, load_map


class GridVectorEnv(VectorEnv):
    """N grid MDPs stepped together.

    ``autoreset_mode``: ``NEXT_STEP`` (gymnasium's default: the step after an episode ends resets
    that env and ignores its action), ``SAME_STEP`` (reset at once; the last observation of the
    ended episode is in ``info["final_obs"]``, its info in ``info["final_info"]``) or
    ``DISABLED`` (call ``reset(options={"reset_mask": mask})`` yourself).
    ``render_mode="rgb_array"``: :meth:`render` returns one map image per env.
    """

    def __init__(
        self,
        num_envs: int = 1,
        map: str | os.PathLike | GridMap = "A",  # noqa: A002 - the design's keyword
        config: GridConfig | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        render_mode: str | None = None,
        **config_kwargs: Any,
    ):
        check_render_mode(render_mode)
        self.grid_map = load_map(map)
        self.config = GridConfig.from_kwargs(config, **config_kwargs)
        self.num_envs = num_envs
        self.mdp = GridMDP(self.grid_map, num_envs, self.config)
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.render_mode = render_mode
        self.metadata = {
            "autoreset_mode": self.autoreset_mode,
            "render_modes": list(RENDER_MODES),
            "render_fps": 4,
        }
        self.single_observation_space = observation_space(
            *self.grid_map.shape, self.grid_map.has_obstacles
        )
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.single_action_space = action_space()
        self.action_space = MultiDiscrete(np.full(num_envs, NUM_ACTIONS))
        self._pending_reset = np.zeros(num_envs, dtype=bool)
        self._all = np.ones(num_envs, dtype=bool)
        self._rngs: list[np.random.Generator] | None = None  # one per env, made on first use
        self._seeds: list[int | None] = [None] * num_envs

    # ------------------------------------------------------------------ seeding
    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:
        """Each env's generator (as :class:`~gymnasium.vector.SyncVectorEnv`)."""
        if self._rngs is None:
            self._rngs = [seeding.np_random()[0] for _ in range(self.num_envs)]
        return tuple(self._rngs)

    @property
    def np_random_seed(self) -> tuple[int | None, ...]:
        """The seed each env's generator was last made from (None: from fresh entropy)."""
        return tuple(self._seeds)

    def _seed_list(self, seed: int | Sequence[int | None] | None) -> list[int | None]:
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, numbers.Integral) and not isinstance(seed, bool):
            return [int(seed) + i for i in range(self.num_envs)]
        if isinstance(seed, (str, bytes)) or not isinstance(seed, (Sequence, np.ndarray)):
            raise ValueError(
                f"seed must be an int, a list of {self.num_envs} seeds or None, got {seed!r}"
            )
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"seed list has {len(seeds)} entries; num_envs is {self.num_envs}")
        for i, s in enumerate(seeds):
            if s is not None and (
                isinstance(s, bool) or not isinstance(s, numbers.Integral) or s < 0
            ):
                raise ValueError(f"seed[{i}] must be a non-negative int or None, got {s!r}")
        return [None if s is None else int(s) for s in seeds]

    def _draw_resets(self, idx: np.ndarray, start, budget):
        """Start cells (row, col), budgets and wind draws of the envs ``idx``, each drawn from
        its own generator in a single env's order (start, budget, wind) unless given."""
        rngs, mdp = self.np_random, self.mdp
        draws = np.zeros((idx.size, 2))  # (start, budget) uniforms, in a single env's order
        wind = np.zeros((idx.size, 3)) if mdp.wind is not None else None
        for j, i in enumerate(idx.tolist()):
            rng = rngs[i]
            if start is None:
                draws[j, 0] = rng.random()
            if budget is None:
                draws[j, 1] = rng.random()
            if wind is not None:
                wind[j] = rng.random(3)
        if start is None:
            cells = mdp.landing_cells[mdp.draw_start_index(draws[:, 0])]
            start = np.stack(np.divmod(cells, mdp.width), axis=1)
        return start, (budget if budget is not None else mdp.draw_budget(draws[:, 1])), wind

    def _reset_envs(self, mask: np.ndarray | None, start=None, budget=None) -> None:
        idx = np.arange(self.num_envs) if mask is None else np.flatnonzero(mask)
        if idx.size == 0:
            return
        starts, budgets, wind = self._draw_resets(idx, start, budget)
        # all given: the MDP draws nothing from the generator argument
        self.mdp.reset(None, mask=mask, start=starts, budget=budgets, wind_draws=wind)
        self._on_reset(idx)

    # ------------------------------------------------------------------ what a backend adds
    def _on_reset(self, idx: np.ndarray) -> None:
        """Backend state of the envs ``idx`` to reset after the MDP drew their episodes."""

    def _transition(self, actions: np.ndarray, active: np.ndarray):
        """One action per env (those not ``active`` wait); ends in ``self.mdp.apply``."""
        return self.mdp.step(actions, active=active)

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ):
        seeds = self._seed_list(seed)
        start, budget, extra = reset_options(options, extra=("reset_mask",))
        mask = extra.get("reset_mask")
        if mask is not None:
            mask = np.asarray(mask, dtype=bool)
        selected = self._all if mask is None else mask
        rngs = list(self.np_random)
        for i, s in enumerate(seeds):
            if s is not None and selected[i]:  # as SyncVectorEnv: only the envs reset
                rngs[i], self._seeds[i] = seeding.np_random(s)
        self._rngs = rngs
        self._reset_envs(mask, start=start, budget=budget)
        self._pending_reset[selected] = False
        return self.mdp.observation(), self._infos()

    def step(self, actions):
        actions = np.asarray(actions)
        if not np.issubdtype(actions.dtype, np.integer) or actions.size != self.num_envs:
            raise ValueError(
                f"actions must be {self.num_envs} integers in 0..{NUM_ACTIONS - 1}, got {actions!r}"
            )
        actions = actions.astype(np.int64, copy=False).reshape(self.num_envs)
        resetting = self._pending_reset
        out = self._transition(actions, ~resetting & ~self.mdp.done)
        terminated = out.terminated & ~resetting
        truncated = np.zeros(self.num_envs, dtype=bool)
        if self.autoreset_mode is AutoresetMode.NEXT_STEP:
            if resetting.any():
                self._reset_envs(resetting)
            self._pending_reset = terminated.copy()
            return self.mdp.observation(), out.reward, terminated, truncated, self._infos()
        if self.autoreset_mode is AutoresetMode.SAME_STEP and terminated.any():
            final_obs, final_info = self.mdp.observation(), self._infos()
            self._reset_envs(terminated)
            infos = self._infos()
            infos.update(final_obs=final_obs, final_info=final_info, _final_obs=terminated.copy())
            infos["_final_info"] = terminated.copy()
            return self.mdp.observation(), out.reward, terminated, truncated, infos
        return self.mdp.observation(), out.reward, terminated, truncated, self._infos()

    # ------------------------------------------------------------------ saving and restoring
    def state_dict(self) -> dict[str, Any]:
        """Everything needed to continue exactly where this env is: the MDP's state arrays,
        which envs reset on their next step, and each env's generator state (copies)."""
        return {
            **self.mdp.state_dict(),
            "pending_reset": self._pending_reset.copy(),
            "rng": [g.bit_generator.state for g in self.np_random],
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """The inverse of :meth:`state_dict`. ``ValueError`` naming the entry that does not fit
        (another ``num_envs``, another map size); nothing changes unless all of it fits."""
        state = dict(state)
        for key in ("pending_reset", "rng"):
            if key not in state:
                raise ValueError(f"env state lacks {key!r}")
        pending = np.asarray(state.pop("pending_reset"))
        if pending.shape != (self.num_envs,) or pending.dtype != bool:
            raise ValueError(
                f"env state 'pending_reset' is {pending.dtype}{list(pending.shape)}; "
                f"this env needs bool[{self.num_envs}]"
            )
        rngs = restore_generators(state.pop("rng"), self.num_envs)
        self.mdp.load_state_dict(state)  # validates all of its arrays before it sets any
        self._pending_reset = pending.copy()
        self._rngs = rngs

    def render(self) -> tuple[np.ndarray, ...] | None:
        """One (H·16, W·16, 3) map image per env (zones, coverage, UAV), as SyncVectorEnv."""
        if self.render_mode != "rgb_array":
            return None

        m = self.mdp
        return tuple(
            grid_image(self.grid_map, m.coverage[i], m.position[i]) for i in range(self.num_envs)
        )

    def _infos(self) -> dict[str, np.ndarray]:
        info = self.mdp.info()
        info.update({f"_{k}": self._all for k in list(info)})
        return info


def restore_generators(states: Any, num_envs: int) -> list[np.random.Generator]:
    """``num_envs`` generators from a checkpoint's ``rng`` list (``bit_generator.state`` each);
    ``ValueError`` naming what does not fit, before anything is changed."""
    if not isinstance(states, (list, tuple)) or len(states) != num_envs:
        count = len(states) if isinstance(states, (list, tuple)) else 1
        raise ValueError(
            f"env state holds {count} generator state(s); this env has {num_envs} slots"
        )
    rngs = []
    for i, rng_state in enumerate(states):
        rng = seeding.np_random()[0]
        try:
            rng.bit_generator.state = rng_state
        except (TypeError, ValueError, KeyError) as exc:
            raise ValueError(f"env state 'rng'[{i}] is not a generator state ({exc})") from None
        rngs.append(rng)
    return rngs
