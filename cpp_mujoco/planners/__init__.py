"""Reference planners: every learned agent is compared against these through the same protocol."""

from cpp_mujoco.grid.way_home import ReturnMargin
from cpp_mujoco.planners.beam_search import BeamSearchPlanner
from cpp_mujoco.planners.optimal import OptimalPlanner
from cpp_mujoco.planners.random_planner import RandomPlanner
from cpp_mujoco.planners.safe_greedy import SafeGreedyPlanner
from cpp_mujoco.planners.safe_greedy_wind import WindSafeGreedyPlanner
from cpp_mujoco.planners.wind_demonstrator import WindDemonstrator

PLANNERS = {
    "random": RandomPlanner,
    "safe-greedy": SafeGreedyPlanner,
    "beam-search": BeamSearchPlanner,
    # for wind (the grid wind option, MuJoCo with wind): priced from the observed wind
    "safe-greedy-wind": WindSafeGreedyPlanner,
    "beam-search-wind": WindDemonstrator,
    # the best mission per episode, solved (OR-Tools CP-SAT); options: make_planner's optimal=
    "optimal": OptimalPlanner,
}
WIND_PLANNERS = ("safe-greedy-wind", "beam-search-wind")  # the ones that keep a ReturnMargin


def make_planner(
    name: str, wind_margin: ReturnMargin | None = None, optimal: dict | None = None,
    fov_side: int = 3,
):  # fmt: skip
    """A reference planner by name (``random``, ``safe-greedy``, ``beam-search``, ``optimal``,
    ``safe-greedy-wind``, ``beam-search-wind``); ``wind_margin`` is the margin the two wind
    planners keep (None: their default), the others price no wind and take none; ``optimal``:
    the exact planner's keyword arguments (``options``, ``cache_folder``, ``jobs``);
    ``fov_side``: the camera's square the planner plans with (the env's ``GridConfig.fov_side``;
    the protocol refuses a planner whose square differs)."""
    try:
        kind = PLANNERS[name]
    except KeyError:
        raise ValueError(f"unknown planner {name!r}; choose from {', '.join(PLANNERS)}") from None
    view = {} if name == "random" else {"fov_side": fov_side}
    if wind_margin is not None and name in WIND_PLANNERS:
        return kind(margin=wind_margin, **view)
    if name == "optimal":
        return kind(**{**(optimal or {}), **view})
    return kind(**view)


__all__ = [
    "PLANNERS",
    "WIND_PLANNERS",
    "BeamSearchPlanner",
    "OptimalPlanner",
    "RandomPlanner",
    "SafeGreedyPlanner",
    "WindDemonstrator",
    "WindSafeGreedyPlanner",
    "make_planner",
]
