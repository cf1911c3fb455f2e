"""What a batch of drones is flying: the kinds of macro-action, per drone the action's running
state, and the failed state checks of a tick — shared by the flight
(:mod:`~cpp_mujoco.physics.flight`) and its tick (:mod:`~cpp_mujoco.physics.tick`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MOVE, HOVER, LAND = 0, 1, 2  # the three kinds of macro-action


@dataclass
class ActionResult:
    """What one macro-step did."""

    duration: float = 0.0  # s of simulated time
    energy: float = 0.0  # J drawn from the battery
    newly_seen: int = 0  # target cells seen for the first time
    arrived: bool = False  # reached the waypoint within tolerances (moves and landings)
    landed: bool = False  # touched down on the landing gear
    tracking_error: float = 0.0  # m, distance from the commanded point at the end
    failure: str | None = None  # why the flight ended physically (battery, flip, …)


# the failed state checks of a tick, in the order they are tested
FAILURES = ("numerical divergence (NaN or unstable acceleration)", "left the arena",
            "flipped over", "diverged from the reference")  # fmt: skip


@dataclass
class MacroActions:
    """Per drone, the macro-action being flown: its clock, goal, limits, and how it ends."""

    res: dict  # the result fields, (n,) arrays
    flying: np.ndarray  # still in the action
    t: np.ndarray  # s since the action (or its emergency landing, or the fall) began
    t0: np.ndarray  # simulated time at the action's start
    goal: np.ndarray  # (n, 3)
    nominal: np.ndarray
    limit: np.ndarray
    arrive: np.ndarray  # a move: done on arrival
    land: np.ndarray  # landing (asked for, or the battery failsafe's)
    begun_landing: np.ndarray  # a landing asked for: it finishes on the reserve
    emergency: np.ndarray  # why the failsafe is landing the drone (object: str or None)
    worst2: np.ndarray  # the largest squared horizontal tracking error
