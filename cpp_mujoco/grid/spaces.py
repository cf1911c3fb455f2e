"""Observation and action spaces, shared by the grid and physics envs so one agent runs on both."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

from cpp_mujoco.grid.actions import NUM_ACTIONS

MAX_WIND = 100.0  # m/s, bound of the wind observation (the physics config rejects faster winds)
MAX_BUDGET = 100_000  # upper bound of the budget observation; larger budgets are rejected
RENDER_MODES = ("rgb_array",)  # every env renders RGB frames: map images or the chase camera


def observation_space(height: int, width: int, obstacles: bool = False) -> spaces.Dict:
    """``map`` (3,H,W) [landing, target, no-fly], ``coverage`` (H,W), ``position`` (H,W) one-hot,
    ``budget`` (1,) remaining movement budget (whole units), ``safety`` (1,) last action rejected,
    ``wind`` (2,) the steady wind's velocity east and north, m/s (zeros in the paper's calm MDP);
    on a map with ``obstacles``, ``obstacle`` (H,W): the cells that block the camera's view (a
    map without keeps the paper's keys, so every agent and client of them reads it as before).
    """
    keys = {
        "map": spaces.MultiBinary((3, height, width)),
        "coverage": spaces.MultiBinary((height, width)),
        "position": spaces.MultiBinary((height, width)),
        "budget": spaces.Box(0.0, float(MAX_BUDGET), shape=(1,), dtype=np.float32),
        "safety": spaces.MultiBinary(1),
        "wind": spaces.Box(-MAX_WIND, MAX_WIND, shape=(2,), dtype=np.float32),
    }
    if obstacles:
        keys["obstacle"] = spaces.MultiBinary((height, width))
    return spaces.Dict(keys)


def action_space() -> spaces.Discrete:
    """0 north, 1 east, 2 south, 3 west, 4 land."""
    return spaces.Discrete(NUM_ACTIONS)


def check_action(action: object) -> int:
    """The action as an ``int``; ``ValueError`` naming it unless it is an integer in 0..4.

    Both single envs use this, so they accept the same things: Python ints and numpy integer
    scalars or 0-d integer arrays (what SB3 and ``action_space.sample()`` pass). Floats (even
    ``2.0``), strings, bools and 1-element arrays are rejected rather than truncated.
    """
    is_int = isinstance(action, int) and not isinstance(action, bool)
    is_np_int = (
        isinstance(action, (np.generic, np.ndarray))
        and action.shape == ()
        and np.issubdtype(action.dtype, np.integer)
    )
    if not (is_int or is_np_int) or not 0 <= int(action) < NUM_ACTIONS:
        raise ValueError(f"action must be an integer in 0..{NUM_ACTIONS - 1}, got {action!r}")
    return int(action)


def reset_options(options: object, extra: tuple[str, ...] = ()) -> tuple[Any, Any, dict[str, Any]]:
    """``(start, budget, extras)`` from ``reset(options=...)``; absent ones are None / left out.

    The one parser for ``Grid-v0``, ``MuJoCo-v0`` and the vector env (which adds ``reset_mask``
    as ``extra``), so all three accept and refuse the same options: a misspelt key is an error
    naming it, never silently a random episode.
    """
    if options is None:
        return None, None, {}
    if not isinstance(options, Mapping):
        raise ValueError(f"reset options must be a dict, got {options!r}")
    rest = dict(options)
    start, budget = rest.pop("start", None), rest.pop("budget", None)
    extras = {k: rest.pop(k) for k in extra if k in rest}
    if rest:
        known = ", ".join(("start", "budget", *extra))
        raise ValueError(f"unknown reset option(s) {sorted(rest)}; known: {known}")
    return start, budget, extras


def check_render_mode(render_mode: str | None) -> str | None:
    """``render_mode`` unless it is neither None nor one of :data:`RENDER_MODES`."""
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise ValueError(
            f"render_mode must be None or one of {list(RENDER_MODES)}, got {render_mode!r}"
        )
    return render_mode
