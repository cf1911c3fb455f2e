"""Greedy evaluation of a policy on a pool's maps: the general agent's validation.

Each map is flown with the paper's protocol (every landing cell × every ``budget_step``-th
budget of its size class) by :func:`~cpp_mujoco.protocol.map_sets.evaluate_maps`, the protocol of
the held-out map sets (which stay the final test), and the figures are means over the maps, so
every map weighs the same whatever its size or landing zone.
"""

from __future__ import annotations

from cpp_mujoco.agent.map_pool import MapPool
from cpp_mujoco.protocol.map_sets import MapSetResult, evaluate_maps
from cpp_mujoco.protocol.policy import Policy


def validate(policy: Policy, pool: MapPool, budget_step: int = 1, name: str | None = None,
             what: str = "validation") -> MapSetResult:  # fmt: skip
    """``policy`` over every map of ``pool`` (its size class's budgets, every ``budget_step``);
    ``name``: the policy's name in the result (default: its own); ``what``: the pool's role."""
    name = name or getattr(policy, "name", type(policy).__name__)
    return evaluate_maps(
        {"name": what, **pool.identity()}, pool.maps, pool.configs, pool.seeds,
        [(name, policy)], budget_step,
    )  # fmt: skip
