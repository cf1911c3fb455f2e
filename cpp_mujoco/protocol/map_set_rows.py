"""The rows of a map-set flight — one per policy and map — flown here or over worker
processes, each kept in a checkpoint as it lands, so an interrupted flight resumes where it
stopped.

Why processes per map: a search policy (``--value-beam``) costs a second or less per episode, a
held-out set tens of thousands of episodes; the maps are independent, so ``workers`` processes
fly them side by side (spawned: torch's threads do not survive a fork; one torch thread each). The
rows come back in the serial order, equal to a serial flight's but for their wall ``seconds``
(``tests/test_map_set_rows.py``). A worker's exception ends the flight with it, naming the policy
and map, and an interrupt (Ctrl-C, SIGTERM) ends it at once: the workers are stopped, not
waited for; rows already landed stay in the checkpoint.

The checkpoint (a JSON file the caller names) maps each row's key — the policy's name and
identity, the map's digest and seed, the budgets, backend, config and physics options — to
the row, so a row is reused only for the very same flight; rows of other flights in the file
are kept. It is rewritten atomically after every row.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing as mp
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cpp_mujoco.grid.mdp import GridConfig
from cpp_mujoco.maps import GridMap
from cpp_mujoco.protocol.evaluate import EvaluationResult, evaluate
from cpp_mujoco.protocol.physics_tasks import one_torch_thread
from cpp_mujoco.protocol.policy import policy_identity
from cpp_mujoco.util.io import atomic_write_text, json_default, json_plain

NUMBERS = ("episodes", "landing_ratio", "coverage_ratio", "mean_return", "mean_steps")
CHECKPOINT_FORMAT = "cpp_mujoco map-set rows v1"


@dataclass
class RowTask:
    """One policy over one map: the protocol of :func:`~cpp_mujoco.protocol.evaluate.evaluate`
    with the map's budgets and config."""

    name: str
    policy: Any
    grid_map: GridMap
    seed: int
    config: GridConfig
    budgets: list[int]
    backend: str = "grid"
    physics: dict[str, Any] = field(default_factory=dict)  # evaluate's MuJoCo options

    def key(self) -> str:
        """What makes two rows the same flight (the physics' workers and engine do not change
        the numbers: :mod:`~cpp_mujoco.protocol.physics_engines`)."""
        physics = {k: v for k, v in self.physics.items() if k not in ("workers", "engine")}
        what = [
            self.name, policy_identity(self.policy), self.grid_map.digest, self.seed,
            self.budgets, self.backend, asdict(self.config), physics,
        ]  # fmt: skip
        text = json.dumps(what, sort_keys=True, default=json_default)
        return hashlib.sha256(text.encode()).hexdigest()[:24]


def example_budget(budgets: Sequence[int]) -> int:
    """The budget of the rows' example episodes: the middle one of those flown."""
    return int(budgets[len(budgets) // 2])


def example_episode(result: EvaluationResult, budget: int) -> dict:
    """The episode from the map's first landing cell at ``budget``: what a figure draws."""
    start = result.starts[0]
    sel = np.flatnonzero((result.budgets == budget) & (result.starts == start).all(axis=1))
    if sel.size == 0:
        raise ValueError(f"no episode from {tuple(start)} with budget {budget}")
    i = int(sel[0])
    cells = result.trajectories[i]
    return {
        "start": [int(start[0]), int(start[1])],
        "budget": int(budget),
        "cells": cells[cells >= 0].tolist(),
        "landed": bool(result.landed[i]),
        "coverage_ratio": float(result.coverage[i]),
        "steps": int(result.steps[i]),
    }


def fly_row(task: RowTask) -> dict:
    """The task's row: the map, the policy, the protocol's figures, the wall time, an example
    episode and the conditions."""
    start = time.perf_counter()
    r = evaluate(
        task.policy, task.grid_map, backend=task.backend, budgets=task.budgets,
        config=task.config, policy_name=task.name, **task.physics,
    )  # fmt: skip
    seconds = time.perf_counter() - start
    summary = r.summary()
    return json_plain(
        {
            "map": task.grid_map.label,
            "seed": task.seed,
            "map_digest": task.grid_map.digest,
            "landing_cells": int(task.grid_map.landing.sum()),
            "policy": task.name,
            "backend": r.backend,
            **{k: summary[k] for k in NUMBERS},
            "seconds": seconds,
            "example": example_episode(r, example_budget(task.budgets)),
            "conditions": r.conditions,
        }
    )


def _fly_in_worker(task: RowTask) -> dict:
    with one_torch_thread():
        return fly_row(task)


class Checkpoint:
    """The rows landed so far, by key, in a JSON file (absent: none yet)."""

    def __init__(self, path: str | Path | None):
        self.path = None if path is None else Path(path)
        self.rows: dict[str, dict] = {}
        if self.path is None or not self.path.exists():
            return
        try:
            data = json.loads(self.path.read_text())
            if data.get("format") != CHECKPOINT_FORMAT or not isinstance(data.get("rows"), dict):
                raise ValueError(f"not a checkpoint of map-set rows ({CHECKPOINT_FORMAT})")
        except (ValueError, UnicodeDecodeError, AttributeError) as e:
            raise ValueError(
                f"{self.path}: unreadable checkpoint ({e}); move it away to fly again"
            ) from None
        self.rows = data["rows"]

    def put(self, key: str, row: dict) -> None:
        self.rows[key] = row
        if self.path is not None:
            text = json.dumps({"format": CHECKPOINT_FORMAT, "rows": self.rows}, indent=1)
            atomic_write_text(self.path, text)


def fly_rows(
    tasks: Sequence[RowTask],
    workers: int | None = None,
    checkpoint: str | Path | None = None,
    on_row: Callable[[], None] | None = None,
) -> list[dict]:
    """Every task's row, in the tasks' order: those in ``checkpoint`` read from it, the others
    flown here (``workers`` None or 1) or over ``workers`` spawned processes, each written to
    the checkpoint as it lands. ``on_row`` is called once per row (a progress bar)."""
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    store = Checkpoint(checkpoint)
    keys = [t.key() for t in tasks]
    todo = [i for i, k in enumerate(keys) if k not in store.rows]
    on_row = on_row or (lambda: None)
    for _ in range(len(tasks) - len(todo)):
        on_row()
    if workers is None or workers == 1 or len(todo) <= 1:
        for i in todo:
            try:
                row = fly_row(tasks[i])
            except Exception as error:
                error.add_note(_where(tasks[i]))
                raise
            store.put(keys[i], row)
            on_row()
    else:
        _fly_over_workers(tasks, keys, todo, workers, store, on_row)
    return [store.rows[k] for k in keys]


def _where(task: RowTask) -> str:
    """The note a failed row's error carries: which policy on which map."""
    return f"flying {task.name} on map {task.grid_map.label}"


def _fly_over_workers(tasks, keys, todo, workers, store, on_row) -> None:
    pool = ProcessPoolExecutor(min(workers, len(todo)), mp.get_context("spawn"))
    try:
        running = {pool.submit(_fly_in_worker, tasks[i]): i for i in todo}
        while running:
            done, _ = wait(running, return_when=FIRST_COMPLETED)  # each row kept as it lands
            for future in done:
                i = running.pop(future)
                error = future.exception()
                if error is not None:
                    error.add_note(_where(tasks[i]))
                    raise error
                store.put(keys[i], future.result())
                on_row()
    except BaseException:
        _stop_workers(pool)  # an error or an interrupt: the rows in flight are lost, not waited for
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Ends the pool's workers now: a row takes minutes, and an interrupted flight must not
    wait for the rows in flight (the landed ones are in the checkpoint)."""
    terminate = getattr(pool, "terminate_workers", None)  # Python 3.14
    if terminate is not None:
        terminate()
        return
    for process in list((pool._processes or {}).values()):  # before 3.14: no public way
        process.terminate()
