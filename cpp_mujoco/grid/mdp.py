"""The paper's grid MDP, for a batch of N environments held in arrays.

This is the one implementation of the rules: the single :class:`~cpp_mujoco.grid.env.GridEnv` is
a batch of one, the vector env a batch of many, evaluation and planners use it directly.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from cpp_mujoco.grid.actions import NUM_ACTIONS
from cpp_mujoco.grid.coverage import mark_fov, view_cells
from cpp_mujoco.grid.safety import SafetyController
from cpp_mujoco.grid.spaces import MAX_BUDGET
from cpp_mujoco.grid.wind import EpisodeWinds, GridWind
from cpp_mujoco.maps import GridMap


@dataclass(frozen=True)
class Rewards:
    """Reward components (paper §II-C); defaults are the design's."""

    coverage: float = 0.4  # r_cov, per target cell seen for the first time
    move: float = -0.2  # r_mov, every step (each step uses one budget unit)
    safety: float = -1.0  # r_sc, per action the safety controller rejects
    crash: float = -150.0  # r_crash, budget exhausted without having landed

    def __call__(self, newly_seen: np.ndarray, rejected: np.ndarray, crashed: np.ndarray):
        return (
            self.coverage * newly_seen + self.move + self.safety * rejected + self.crash * crashed
        )


@dataclass(frozen=True)
class GridConfig:
    """Everything configurable about the grid MDP."""

    fov_side: int = 3  # side of the square camera footprint, in cells, centred on the UAV
    min_budget: int = 25  # initial movement budget is uniform over min..max (inclusive)
    max_budget: int = 75
    rewards: Rewards = field(default_factory=Rewards)
    # None: every action costs one unit (the paper). A GridWind: a per-episode wind sets each
    # action's cost from physics-calibrated energies, and the budget becomes a float
    wind: GridWind | None = None

    def __post_init__(self) -> None:
        if isinstance(self.rewards, dict):
            object.__setattr__(self, "rewards", Rewards(**self.rewards))
        if isinstance(self.wind, dict):
            object.__setattr__(self, "wind", GridWind(**self.wind))
        if self.wind is not None and not isinstance(self.wind, GridWind):
            raise ValueError(f"wind must be None or a GridWind, got {self.wind!r}")
        if self.fov_side < 1:
            raise ValueError(f"fov_side must be >= 1, got {self.fov_side}")
        if not 1 <= self.min_budget <= self.max_budget <= MAX_BUDGET:
            raise ValueError(
                f"need 1 <= min_budget <= max_budget, got {self.min_budget}..{self.max_budget}"
            )

    @classmethod
    def from_kwargs(cls, config: GridConfig | None = None, **kwargs) -> GridConfig:
        """A config from ``gymnasium.make`` keyword arguments; unknown keys are an error."""
        names = {f.name for f in fields(cls)}
        unknown = set(kwargs) - names
        if unknown:
            raise TypeError(
                f"unknown grid config option(s) {sorted(unknown)}; known: {sorted(names)}"
            )
        if config is None:
            return cls(**kwargs)
        return cls(**{**{n: getattr(config, n) for n in names}, **kwargs})


@dataclass
class Outcome:
    """What one action did to each environment, however it was simulated (arrays (N,)).

    The grid derives it from the safety controller and the square field of view, the physics
    backend from the flight (budget from the energy drawn, coverage from the camera). Either way
    :meth:`GridMDP.apply` turns it into reward and flags, so those rules exist once.
    """

    next_cell: np.ndarray  # flat cell the UAV is over afterwards (where it was, if rejected)
    rejected: np.ndarray  # the safety controller rejected the action: the UAV hovered
    landed: np.ndarray  # it touched down this step
    spent: np.ndarray  # budget units used (the grid: 1; physics: the energy drawn, in units)
    newly_seen: np.ndarray  # target cells seen for the first time (coverage is already marked)
    failed: np.ndarray | None = None  # the flight ended physically (battery, flip, …)


@dataclass
class StepOutcome:
    """Per-environment results of one batched step (arrays of shape (N,))."""

    reward: np.ndarray
    terminated: np.ndarray
    rejected: np.ndarray
    crashed: np.ndarray
    newly_seen: np.ndarray


class GridMDP:
    """N copies of the grid MDP. State lives in flat arrays; cells are indexed ``row * W + col``."""

    # the per-environment state arrays: all a saved run needs (:meth:`state_dict`)
    STATE = (
        "position", "budget", "coverage", "seen_targets", "landed", "crashed", "rejected",
        "initial_budget",
    )  # fmt: skip

    def __init__(self, grid_map: GridMap, num_envs: int = 1, config: GridConfig | None = None):
        if num_envs < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        self.map = grid_map
        self.config = config or GridConfig()
        self.num_envs = num_envs
        self.height, self.width = grid_map.shape
        self.safety = SafetyController(grid_map)
        self.target = grid_map.target.reshape(-1)
        # the field of view as (cells, side²) indices, not a (cells, cells) mask: memory ∝ cells;
        # what obstacles hide is not valid (it is neither counted nor marked as seen)
        self.fov_cells, fov_valid = view_cells(grid_map, self.config.fov_side)
        self.fov_counted = fov_valid & self.target[self.fov_cells]
        self.num_targets = int(self.target.sum())
        self.landing_cells = np.flatnonzero(grid_map.landing)
        self.map_layers = grid_map.layers.astype(np.int8)
        self.map_layers.flags.writeable = False
        self._map_view = np.broadcast_to(self.map_layers, (num_envs, *self.map_layers.shape))
        obstacle = grid_map.obstacle.astype(np.int8)
        self._obstacle_view = (
            np.broadcast_to(obstacle, (num_envs, *obstacle.shape)) if grid_map.has_obstacles
            else None
        )  # fmt: skip
        self._rows = np.arange(num_envs)

        n, cells = num_envs, self.height * self.width
        self.wind = self.config.wind
        self.winds = EpisodeWinds(num_envs, self.wind)  # observed always; costs with the option
        self.state_keys = self.STATE + (EpisodeWinds.STATE if self.wind is not None else ())
        self.position = np.zeros(n, dtype=np.int64)
        # whole units in the paper's MDP; with wind, what is left of a float budget
        self.budget = np.zeros(n, dtype=np.float64 if self.wind is not None else np.int64)
        self.coverage = np.zeros((n, cells), dtype=bool)
        self.seen_targets = np.zeros(n, dtype=np.int64)
        self.landed = np.zeros(n, dtype=bool)
        self.crashed = np.zeros(n, dtype=bool)
        self.rejected = np.zeros(n, dtype=bool)  # the safety flag: the last action was rejected
        self.initial_budget = np.zeros(n, dtype=np.int64)

    # ------------------------------------------------------------------ state transitions
    @property
    def steps(self) -> np.ndarray:
        """Budget units used so far in each episode (the paper: actions taken)."""
        return self.initial_budget - self.budget

    @property
    def out_of_budget(self) -> np.ndarray:
        """Less than one whole unit left: the paper's budget 0, and what the physics env sees
        (it floors the pack's remaining energy to whole units)."""
        return self.budget < 1

    @property
    def done(self) -> np.ndarray:
        """Landed, out of budget, or crashed (a physical failure can end a flight early)."""
        return self.landed | self.out_of_budget | self.crashed

    def reset(
        self,
        rng: np.random.Generator,
        mask: np.ndarray | None = None,
        start=None,
        budget=None,
        wind_draws=None,
    ) -> None:
        """Reset the environments selected by ``mask`` (all if None).

        ``start``: (row, col) or an array of them, each a landing cell; default uniform over the
        landing cells. ``budget``: positive int(s); default uniform over min..max budget.
        With the wind option, ``wind_draws`` (k, 3) uniforms pick each episode's wind
        (:meth:`GridWind.draw`); default drawn from ``rng``.
        Random draws happen in this order (start, budget, wind) so any batch of the same seed
        draws the same episodes.
        """
        idx = np.arange(self.num_envs) if mask is None else np.flatnonzero(mask)
        k = idx.size
        if start is None:
            cells = self.landing_cells[self.draw_start_index(rng.random(k))]
        else:
            cells = self._start_cells(start, k)
        if budget is None:
            budgets = self.draw_budget(rng.random(k))
        else:
            budgets = np.broadcast_to(np.asarray(budget), (k,))
            if (
                not np.issubdtype(budgets.dtype, np.integer)
                or not ((budgets >= 1) & (budgets <= MAX_BUDGET)).all()
            ):
                raise ValueError(f"budget must be an integer in 1..{MAX_BUDGET}, got {budget!r}")
        self.position[idx] = cells
        self.budget[idx] = budgets
        self.coverage[idx] = False
        self.seen_targets[idx] = 0
        self.landed[idx] = False
        self.crashed[idx] = False
        self.rejected[idx] = False
        self.initial_budget[idx] = budgets
        if self.wind is not None:
            if wind_draws is None:
                wind_draws = rng.random((k, 3))
            self.winds.draw(idx, wind_draws)

    # Draws map uniform [0, 1) doubles to starts and budgets: one ``Generator.random`` call per
    # value is several times cheaper than ``Generator.integers``, which matters where each env
    # draws from its own generator (the vector env's resets).
    def draw_start_index(self, u: np.ndarray | float) -> np.ndarray:
        """Index into ``landing_cells`` for uniform draw(s) ``u`` in [0, 1)."""
        return (np.asarray(u) * self.landing_cells.size).astype(np.int64)

    def draw_budget(self, u: np.ndarray | float) -> np.ndarray:
        """Budget uniform over min..max (inclusive) for uniform draw(s) ``u`` in [0, 1)."""
        lo, hi = self.config.min_budget, self.config.max_budget + 1
        return lo + (np.asarray(u) * (hi - lo)).astype(np.int64)

    def restore(self, position: np.ndarray, budget: np.ndarray, coverage: np.ndarray) -> None:
        """Put every environment into a given mid-episode state (flat cells, budgets, (N, H·W)
        coverage) — for planners that simulate ahead from an observation."""
        budget = np.asarray(budget)
        whole = np.maximum(np.floor(budget), 1).astype(np.int64)
        self.reset(np.random.default_rng(0), budget=whole)
        self.budget[:] = budget if self.wind is not None else whole
        self.position[:] = position
        self.coverage[:] = coverage
        self.seen_targets[:] = (self.coverage & self.target).sum(axis=1)

    def _start_cells(self, start, k: int) -> np.ndarray:
        rc = np.asarray(start)
        if rc.shape == (2,):
            rc = np.broadcast_to(rc, (k, 2))
        if rc.shape != (k, 2) or not np.issubdtype(rc.dtype, np.integer):
            raise ValueError(f"start must be an integer (row, col) or {k} of them, got {start!r}")
        r, c = rc[:, 0], rc[:, 1]
        inside = (r >= 0) & (r < self.height) & (c >= 0) & (c < self.width)
        if not inside.all():
            bad = tuple(int(v) for v in rc[~inside][0])
            raise ValueError(f"start {bad} is outside the {self.height}x{self.width} grid")
        cells = r * self.width + c
        on_landing = self.map.landing.reshape(-1)[cells]
        if not on_landing.all():
            bad = tuple(int(v) for v in rc[~on_landing][0])
            raise ValueError(f"start {bad} is not a landing cell of map {self.map.name!r}")
        return cells

    def step(self, actions: np.ndarray, active: np.ndarray | None = None) -> StepOutcome:
        """Apply one action per environment, in the paper's order: the safety controller
        decides, the UAV moves (or hovers), one budget unit is spent, the field of view is
        marked (the landing step included), then :meth:`apply` gives reward and termination.

        Environments not ``active`` (default: those already done) keep their state and get
        reward 0 and ``terminated`` as it was.
        """
        actions = np.asarray(actions, dtype=np.int64)
        if actions.shape != (self.num_envs,):
            raise ValueError(f"expected {self.num_envs} actions, got shape {actions.shape}")
        if (actions.view(np.uint64) >= NUM_ACTIONS).any():  # negatives wrap to huge values
            raise ValueError(f"actions must be in 0..{NUM_ACTIONS - 1}, got {actions}")
        if active is None:
            active = ~self.done
        everyone = bool(active.all())  # the common case skips the masking below
        next_cell, rejected, lands = self.safety.decide(self.position, actions)
        if not everyone:
            rejected &= active
            lands &= active
            next_cell = np.where(active, next_cell, self.position)
        marked = None if everyone else np.flatnonzero(active)
        newly_seen = mark_fov(self.coverage, self.fov_cells, self.fov_counted, next_cell, marked)
        spent = active if self.wind is None else self.winds.costs(actions, rejected, lands, active)
        outcome = Outcome(next_cell, rejected, lands, spent, newly_seen)
        return self.apply(outcome, None if everyone else active)

    def apply(self, outcome: Outcome, active: np.ndarray | None = None) -> StepOutcome:
        """The rules of one step, for an outcome from either backend: move, spend, flag, count,
        then reward (paper §II-C), crash (out of budget unlanded, or a physical failure) and
        termination. ``active`` (default all) masks crashes and rewards of envs not stepped.
        """
        self.position = outcome.next_cell
        self.landed |= outcome.landed
        self.budget -= outcome.spent
        self.rejected = outcome.rejected  # the safety flag of the next observation
        self.seen_targets += outcome.newly_seen
        out_of_budget = self.out_of_budget
        crashed = out_of_budget & ~self.landed
        if outcome.failed is not None:
            crashed |= outcome.failed
        if active is not None:
            crashed &= active
        self.crashed |= crashed
        reward = self.config.rewards(outcome.newly_seen, outcome.rejected, crashed)
        if active is not None:
            reward *= active
        terminated = self.landed | out_of_budget | self.crashed
        return StepOutcome(reward, terminated, outcome.rejected, crashed, outcome.newly_seen)

    # ------------------------------------------------------------------ saving and restoring
    def state_dict(self) -> dict[str, np.ndarray]:
        """Copies of the per-environment state arrays (:data:`STATE`, and
        :data:`EpisodeWinds.STATE` with the wind option), e.g. for a checkpoint."""
        return {k: self._array(k).copy() for k in self.state_keys}

    def _array(self, key: str) -> np.ndarray:
        return getattr(self.winds if key in EpisodeWinds.STATE else self, key)

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """The inverse of :meth:`state_dict`. ``ValueError`` naming the first entry that is
        missing, unknown or of another shape or kind; nothing is set unless all of them fit."""
        unknown = set(state) - set(self.state_keys)
        if unknown:
            raise ValueError(f"unknown env state entries {sorted(unknown)}")
        arrays = {}
        for k in self.state_keys:
            if k not in state:
                raise ValueError(f"env state lacks {k!r}")
            mine, value = self._array(k), np.asarray(state[k])
            if value.shape != mine.shape or value.dtype.kind != mine.dtype.kind:
                raise ValueError(
                    f"env state {k!r} is {value.dtype}{list(value.shape)}; "
                    f"this env needs {mine.dtype}{list(mine.shape)}"
                )
            arrays[k] = value.astype(mine.dtype)  # a copy, C-contiguous as mark_fov needs
        for k, value in arrays.items():
            if k == "coverage":
                self.coverage[...] = value  # in place: the flight's camera marks this array
            else:
                setattr(self.winds if k in EpisodeWinds.STATE else self, k, value)
        self.winds.loaded()

    # ------------------------------------------------------------------ views of the state
    def observation(self) -> dict[str, np.ndarray]:
        """Batched observation (leading dimension N). ``map`` (and ``obstacle``, on a map with
        obstacles) are read-only broadcast views."""
        n, h, w = self.num_envs, self.height, self.width
        position = np.zeros((n, h * w), dtype=np.int8)
        position[self._rows, self.position] = 1
        obs = {
            "map": self._map_view,
            "coverage": self.coverage.view(np.int8).reshape(n, h, w).copy(),
            "position": position.reshape(n, h, w),
            "budget": np.floor(self.budget).astype(np.float32)[:, None],  # whole units
            "safety": self.rejected.view(np.int8)[:, None].copy(),
            "wind": self.winds.vector.copy(),
        }
        if self._obstacle_view is not None:
            obs["obstacle"] = self._obstacle_view
        return obs

    def observation_of(self, i: int) -> dict[str, np.ndarray]:
        """Environment ``i``'s observation, arrays of its own (no leading dimension)."""
        obs = {k: v[i] for k, v in self.observation().items()}
        obs["map"] = obs["map"].copy()  # the batch shares one read-only map; hand out our own
        if "obstacle" in obs:
            obs["obstacle"] = obs["obstacle"].copy()
        return obs

    def info_of(self, i: int) -> dict:
        """Environment ``i``'s info as Python scalars (the single envs' ``info``)."""
        return {
            "position": divmod(int(self.position[i]), self.width),
            "budget": int(np.floor(self.budget[i])),
            "landed": bool(self.landed[i]),
            "crashed": bool(self.crashed[i]),
            "rejected": bool(self.rejected[i]),
            "coverage_ratio": int(self.seen_targets[i]) / self.num_targets,
        }

    def info(self) -> dict[str, np.ndarray]:
        rows, cols = np.divmod(self.position, self.width)
        return {
            "position": np.stack([rows, cols], axis=1),
            "budget": np.floor(self.budget).astype(np.int64),
            "landed": self.landed.copy(),
            "crashed": self.crashed.copy(),
            "rejected": self.rejected.copy(),
            "coverage_ratio": self.seen_targets / self.num_targets,
        }
