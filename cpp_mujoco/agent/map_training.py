"""The paper's run: one agent trained and judged on one map.

:func:`map_parts` builds its :class:`~cpp_mujoco.agent.training_parts.TrainingParts`: the grid's
vector env on the config's map (or, with ``backend="mujoco"``, several weathers in physics:
:mod:`~cpp_mujoco.physics.envs.mixed_wind`), one replay memory, the paper's network, the guide
planner and the demonstrations of that map. Evaluation flies the paper's protocol on the grid.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.agent import load_agent
from cpp_mujoco.agent.checkpoint import CheckpointError, is_general, load_checkpoint
from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.demonstrations import record_demonstrations
from cpp_mujoco.agent.network import QNetwork, check_can_start_from
from cpp_mujoco.agent.replay import ReplayBuffer
from cpp_mujoco.agent.training_parts import TrainingParts
from cpp_mujoco.agent.training_state import RESUMABLE_CHANGES, changed_settings
from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.planners import make_planner
from cpp_mujoco.protocol.evaluate import EvaluationResult, evaluate, protocol_budgets
from cpp_mujoco.protocol.policy import Policy


class OneMap:
    """The map source of a per-map run: its map, judged by the paper's protocol on the grid."""

    def __init__(self, config: TrainConfig, grid_map: GridMap):
        self.config, self.grid_map = config, grid_map
        self.agent_name = f"ddqn-{grid_map.label}"
        self.log_title = f"DDQN training on map {grid_map.label}"
        self.map_name, self.digest = grid_map.label, grid_map.digest
        self.judged_on = "evaluation"

    def budget_step(self, full: bool) -> int:
        return 1 if full else self.config.eval_budget_step

    def evaluate(self, agent: Policy, budget_step: int) -> EvaluationResult:
        """Greedy evaluation: every landing cell × budgets every ``budget_step``."""
        grid_config = self.config.grid_config
        budgets = protocol_budgets(grid_config, budget_step)
        return evaluate(agent, self.grid_map, budgets=budgets, config=grid_config)

    def complete(self, result: EvaluationResult, budget_step: int) -> None:
        """Nothing: the per-map tables put the planners beside the agent themselves."""

    def payload(self) -> dict:
        return {}

    def read_resumable(self, path: Path, config: TrainConfig) -> tuple[dict, TrainConfig]:
        state = load_checkpoint(path, map_shape=self.grid_map.shape)
        check_resumable(path, state, config, self.grid_map)
        return state, config


def check_resumable(path: Path, state: dict, config: TrainConfig, grid_map: GridMap) -> None:
    """A resume must continue the same run: the same map cells and the same learning settings
    (only :data:`~cpp_mujoco.agent.training_state.RESUMABLE_CHANGES` may differ), else
    :class:`CheckpointError` naming them."""
    if is_general(state):
        raise CheckpointError(f"{path} is a general agent's run; resume it with train-general")
    try:
        stored = TrainConfig.from_dict(state["config"])
    except (TypeError, ValueError) as exc:
        raise CheckpointError(f"{path}: its stored config is invalid ({exc})") from None
    digest = state.get("map_digest")
    if (digest and digest != grid_map.digest) or (
        not digest and stored.map != config.map and load_map(stored.map).name != grid_map.name
    ):
        raise CheckpointError(
            f"{path} was trained on map {state.get('map')!r} ({stored.map}), "
            f"not on {config.map!r} (map {grid_map.label}, cells {grid_map.digest})"
        )
    changed = changed_settings(stored.to_dict(), config.to_dict(), RESUMABLE_CHANGES | {"map"})
    if changed:
        raise CheckpointError(
            f"{path}: resume with the run's own settings; these differ: {'; '.join(changed)}"
        )


def starting_network(config: TrainConfig) -> QNetwork | None:
    """The network of the agent ``config.init_from`` names (bundled name or file), checked to fit
    the run's map and wind inputs; None without one."""
    if not config.init_from:
        return None
    network = load_agent(config.init_from).network
    check_can_start_from(network, *load_map(config.map).shape, config.wind is not None)
    return network


def map_parts(config: TrainConfig, init: QNetwork | None = None) -> TrainingParts:
    """A per-map run's parts; ``init``: the starting network (default: :func:`starting_network`),
    loaded into the paper's (its wind inputs, if new, start at zero weight)."""
    c = config
    init = init if init is not None else starting_network(c)
    grid_map = load_map(c.map)
    if c.backend == "mujoco":
        from cpp_mujoco.physics.envs.mixed_wind import MixedWindVectorEnv  # heavy: MuJoCo

        env = MixedWindVectorEnv.for_training(c, grid_map)
    else:
        env = gym.make_vec(
            "cpp_mujoco/Grid-v0",
            num_envs=c.num_envs,
            map=grid_map,
            config=c.grid_config,
            autoreset_mode="SameStep",
        )
    h, w = grid_map.shape

    def network(config: TrainConfig) -> QNetwork:
        net = QNetwork(h, w, wind_inputs=config.wind is not None)
        if init is not None:  # fine-tuning: a resume then overwrites these weights
            net.load_narrower(init)
        return net

    demos = None
    if c.demo_fraction > 0:
        planner = make_planner(c.demo_planner, c.wind_margin)
        demos = record_demonstrations(grid_map, c.grid_config, planner, c.n_step, c.gamma)
    return TrainingParts(
        maps=OneMap(c, grid_map),
        env=env,
        replay=ReplayBuffer(c.buffer_size, c.num_envs, grid_map.layers, c.n_step, c.gamma),
        network=network,
        guide=make_planner(c.guide, c.wind_margin) if c.guide_fraction > 0 else None,
        demos=demos,
    )
