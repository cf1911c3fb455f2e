"""Reference planners: every learned agent is compared against these through the same protocol."""

from cpp_mujoco.planners.beam_search import BeamSearchPlanner
from cpp_mujoco.planners.random_planner import RandomPlanner
from cpp_mujoco.planners.safe_greedy import SafeGreedyPlanner

PLANNERS = {
    "random": RandomPlanner,
    "safe-greedy": SafeGreedyPlanner,
    "beam-search": BeamSearchPlanner,
}


def make_planner(name: str):
    """A reference planner by name (``random``, ``safe-greedy``, ``beam-search``)."""
    try:
        return PLANNERS[name]()
    except KeyError:
        raise ValueError(f"unknown planner {name!r}; choose from {', '.join(PLANNERS)}") from None


__all__ = ["PLANNERS", "BeamSearchPlanner", "RandomPlanner", "SafeGreedyPlanner", "make_planner"]
