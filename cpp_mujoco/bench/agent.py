"""Training throughput: gradient updates/s and environment steps/s of the DDQN training loop."""

from __future__ import annotations

import tempfile
import time

import torch

from cpp_mujoco.agent.config import TrainConfig
from cpp_mujoco.agent.ddqn import ddqn_update
from cpp_mujoco.agent.network import QNetwork
from cpp_mujoco.agent.train import Trainer


def benchmark_training(
    map_name: str = "A", updates: int = 100, device: str = "cpu", **overrides
) -> dict:
    """Time the training loop (no evaluation, no checkpoints) on ``map_name``.

    Returns ``updates_per_s`` and ``env_steps_per_s`` of the full loop (collection + learning),
    ``collect_env_steps_per_s`` of collection alone (batched forward + soft-max + env step) and
    ``update_ms`` for one gradient update at the configured batch size, and ``setup_s`` for building
    the trainer (the planner's demonstrations are recorded there).
    """
    config = TrainConfig(
        map=map_name,
        device=device,
        total_updates=updates,
        eval_every=10**9,
        checkpoint_every=10**9,
        **overrides,
    )
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        trainer = Trainer(config, tmp)
        setup_s = time.perf_counter() - t0
        # collection alone (this also fills the replay memory past learning_starts)
        t0 = time.perf_counter()
        while len(trainer.replay) < max(config.learning_starts, config.batch_size * 4):
            trainer.collect()
        collect_s = time.perf_counter() - t0
        collect_rate = trainer.env_steps / collect_s
        for _ in range(3):  # warm-up
            trainer.update()
        t0 = time.perf_counter()
        for _ in range(10):
            trainer.update()
        update_ms = (time.perf_counter() - t0) / 10 * 1000
        # the loop as it trains: collect + updates_per_step updates
        u0, s0, t0 = trainer.updates, trainer.env_steps, time.perf_counter()
        while trainer.updates - u0 < updates:
            trainer.collect()
            trainer.update_credit += config.updates_per_step
            while trainer.update_credit >= 1.0:
                trainer.update_credit -= 1.0
                trainer.update()
        dt = time.perf_counter() - t0
    return {
        "map": map_name,
        "device": device,
        "threads": torch.get_num_threads(),
        "num_envs": config.num_envs,
        "batch_size": config.batch_size,
        "updates_per_step": config.updates_per_step,
        "updates_per_s": (trainer.updates - u0) / dt,
        "env_steps_per_s": (trainer.env_steps - s0) / dt,
        "collect_env_steps_per_s": collect_rate,
        "update_ms": update_ms,
        "setup_s": setup_s,
        "demonstrations": len(trainer.demos) if trainer.demos else 0,
    }


def update_ms(compile_network: bool, updates: int = 40, batch_size: int = 128) -> dict:
    """One DDQN update of the paper's network (16×16, half the batch demonstrations), eager or
    with ``torch.compile`` — the measurement behind training eagerly."""
    torch.manual_seed(0)
    online, target = QNetwork(16, 16), QNetwork(16, 16)
    run_online = torch.compile(online) if compile_network else online
    run_target = torch.compile(target) if compile_network else target
    optimizer = torch.optim.Adam(online.parameters(), lr=1e-4)
    b = batch_size
    batch = {
        "grid": torch.rand(b, 5, 16, 16),
        "budget": torch.rand(b, 1) * 75,
        "action": torch.randint(5, (b,)),
        "return": torch.rand(b),
        "next_grid": torch.rand(b, 5, 16, 16),
        "next_budget": torch.rand(b, 1) * 75,
        "discount": torch.full((b,), 0.95),
        "demo": torch.arange(b) < b // 2,
    }

    def step():
        ddqn_update(
            run_online, run_target, optimizer, batch, tau=0.01, loss_kind="huber", margin=0.5
        )

    t0 = time.perf_counter()
    for _ in range(5):  # warm-up (compilation happens here)
        step()
    warmup_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(updates):
        step()
    return {
        "compile": compile_network,
        "update_ms": (time.perf_counter() - t0) / updates * 1000,
        "warmup_s": warmup_s,
    }


def run() -> dict:
    """The ``training`` section as ``cpp-mujoco benchmark`` runs it."""
    return benchmark_training(updates=100)


if __name__ == "__main__":
    import json
    import sys

    if "--compile" in sys.argv:  # python -m cpp_mujoco.bench.agent --compile
        print(json.dumps([update_ms(False), update_ms(True)], indent=2))
    else:
        print(json.dumps(benchmark_training(), indent=2))
