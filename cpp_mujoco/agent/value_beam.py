"""Search with the learned values: beam search whose exploring half ranks paths by the targets
they have seen plus the agent's Q-value of the move that made them.

The plain beam keeps the paths that have seen the most and lie nearest to unseen targets: it
sees only the step in front of it. An agent's Q-value of a move is its estimate of the reward
still to come — in target cells, ``Q / r_cov`` (the move penalty and the discount make it a
short, rough horizon) — so the beam keeps paths worth more further on. Half of the beam still
ranks by the way home, so it keeps paths that can land. The agent's own mission (its network
and rules, played from the same state) is the incumbent: where it sees more than the beam's
best, it is the plan, so the search is never worse than the agent.

The network reads each kept path once per depth, ``width`` readings per episode and step, all
of a batch's episodes in one pass: it costs what the network costs, planned at the first step
(and again wherever the flight leaves the plan, as under physics).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.policy import GreedyAgent
from cpp_mujoco.grid.graph import MapGraph
from cpp_mujoco.grid.mdp import GridConfig, GridMDP, Rewards
from cpp_mujoco.maps import GridMap
from cpp_mujoco.planners import make_planner
from cpp_mujoco.planners.beam_search import DEFAULT_WIDTH, ActionValues, BeamSearchPlanner

VALUE_BEAM = "value-beam"


class ValueBeamAgent(BeamSearchPlanner):
    """``agent``'s Q-values ranking a beam of ``width`` paths per episode; results name it
    ``NAME+value-beam`` (``[width W]`` where not the default) and record the agent's rules."""

    def __init__(self, agent: GreedyAgent, width: int = DEFAULT_WIDTH, fov_side: int = 3):
        super().__init__(width, fov_side)
        self.agent = agent
        self.name = f"{agent.name}+{VALUE_BEAM}" + (
            "" if width == DEFAULT_WIDTH else f"[width {width}]"
        )
        self.metadata = agent.metadata  # the file it was loaded from, for the results

    def _values(self, g: MapGraph) -> ActionValues:
        return lambda cells, left, coverage: self.action_values(g.grid_map, cells, left, coverage)

    def _incumbent(self) -> GreedyAgent:
        return self.agent

    def action_values(
        self, grid_map: GridMap, cells: np.ndarray, left: np.ndarray, coverage: np.ndarray
    ) -> np.ndarray:
        """(R, 5) target cells each action is still worth from R beam rows on ``grid_map``, as
        the network reads them (calm air: the beam plans for it)."""
        mdp = GridMDP(grid_map, cells.size, GridConfig(fov_side=self.fov_side))
        mdp.restore(cells, left, coverage)
        return self.agent.network_q_values(mdp.observation()) / Rewards().coverage

    @property
    def map_shape(self) -> tuple[int, int] | None:
        """The agent's: a per-map agent's map size, None for a general agent's any size."""
        return self.agent.map_shape

    def fits(self, grid_map: GridMap) -> str | None:
        """The agent's own answer: a per-map agent searches only its map."""
        return self.agent.fits(grid_map)

    def identity(self) -> dict[str, Any]:
        """The agent's network and rules (those of its incumbent missions) and the beam."""
        return {**self.agent.identity(), "search": {"name": VALUE_BEAM, "width": self.width}}


def split_search(spec: str) -> tuple[str, bool]:
    """``(agent spec, searches)`` of a policy spec: ``NAME+value-beam`` is agent NAME (a bundled
    name or a file) searching with its values; anything else is an agent alone."""
    agent, plus, search = spec.rpartition("+")
    return (agent, True) if plus and search == VALUE_BEAM else (spec, False)


def load_policy(spec: str, width: int | None = None) -> GreedyAgent | ValueBeamAgent:
    """An agent by spec: ``general`` is the network with its rules, ``general+value-beam`` the
    same agent searching with its values (the bundled general policy in calm air); ``width``
    (paths per episode) makes any agent search."""
    agent_spec, search = split_search(spec)
    agent = load_agent(agent_spec)
    return ValueBeamAgent(agent, width or DEFAULT_WIDTH) if search or width else agent


def make_demonstrator(name: str, wind_margin=None):
    """A teacher by name: a planner (:func:`~cpp_mujoco.planners.make_planner`), or
    ``AGENT+value-beam`` — an agent (bundled name or file) searching with its values, the
    affordable teacher nearest the best missions (1–2 points under them on the 16×16 optimum
    samples, where beam search is 4–5)."""
    if split_search(name)[1]:
        return load_policy(name)
    return make_planner(name, wind_margin)
