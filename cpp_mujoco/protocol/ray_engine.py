"""Ray as the physics protocol's engine: the same chunks as the local pool, as Ray tasks.

Why Ray: the local pool ends at the cores of one machine; a wind sweep is thousands of
independent episodes, and Ray spreads them over a cluster (``ray start --head`` on one machine,
``ray start --address=HEAD:6379`` on the others, then ``RAY_ADDRESS=HEAD:6379`` or
``ray_address=`` here). Each chunk is one task running :func:`~cpp_mujoco.protocol.physics_engines.
fly_chunk` on one CPU; the job (policy, map, options) is put into the object store once, and
each worker process builds its env and policy on its first chunk of the job.

What is retried: a task whose worker process died (killed, out of memory, a crash in native
code) runs again elsewhere, up to ``MAX_RETRIES`` times — the episodes are seeded by their index,
so a retry gives the same numbers. What is not: an exception raised by the policy or the env is
a bug or a bad input, not bad luck; it ends the run at once with that exception (its type,
message and the note naming the episode), and the tasks not yet done are cancelled.

The workers import ``cpp_mujoco``: a local runtime runs them on this interpreter, so they see
what it sees; on a cluster, install the package on every node (``pip install -e .[ray]`` in the
same path) or start Ray yourself with ``ray.init(address=..., runtime_env={"working_dir": "."})``
before evaluating — a runtime already initialised in this process is used as it is.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from cpp_mujoco.protocol.episode import EpisodeRecord
from cpp_mujoco.protocol.physics_tasks import Job, Task, fly_chunk

MAX_RETRIES = 3  # runs of a task whose worker process died, after the first
INSTALL_HINT = "pip install -e .[ray]  (or: pip install 'cpp-mujoco[ray]')"


class RayMissingError(ImportError):
    """Ray is an optional extra; this says how to install it."""


def import_ray() -> Any:
    """The ``ray`` module, or :class:`RayMissingError` naming the extra that brings it."""
    try:
        import ray  # optional: the ray extra
    except ImportError as exc:
        raise RayMissingError(
            f"the Ray engine needs Ray, which is not installed: {INSTALL_HINT}"
        ) from exc
    return ray


def add_ray_options(parser) -> None:
    """``--ray`` and ``--ray-address`` on a script's argument parser."""
    parser.add_argument("--ray", action="store_true", help="fly on Ray (pip install -e .[ray])")
    parser.add_argument(
        "--ray-address", help="Ray cluster to fly on (default: RAY_ADDRESS, else a local one)"
    )


def ray_option_error(args) -> str | None:
    """What is wrong with a script's ``--ray`` options (None: nothing), before anything runs."""
    if args.ray_address and not args.ray:
        return "--ray-address needs --ray"
    if args.ray:
        try:
            import_ray()
        except ImportError as exc:
            return str(exc)
    return None


@contextmanager
def ray_runtime(address: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """Ray, initialised for the ``with`` block: the runtime already initialised in this process
    if any (left running), else a connection to ``address`` or ``RAY_ADDRESS`` (a cluster; only
    the connection is closed afterwards), else a local runtime with ``workers`` CPUs (default:
    all cores), shut down afterwards. Wrap several evaluations in one block to start Ray once."""
    ray = import_ray()
    if ray.is_initialized():
        yield ray
        return
    address = address or os.environ.get("RAY_ADDRESS") or None
    if address:
        ray.init(address=address, include_dashboard=False)
    else:  # "local": a fresh runtime even when a `ray start` one runs here (give its address)
        ray.init(address="local", num_cpus=workers or os.cpu_count() or 1, include_dashboard=False)
    try:
        yield ray
    finally:
        ray.shutdown()


def fly_on_ray(
    job: Job,
    chunks: list[list[Task]],
    bar,
    workers: int | None = None,
    address: str | None = None,
) -> list[EpisodeRecord]:
    """Every chunk as one Ray task; records as they arrive (``bar`` follows), in no order."""
    with ray_runtime(address, workers) as ray:
        remote = ray.remote(fly_chunk).options(
            num_cpus=1, max_retries=MAX_RETRIES, retry_exceptions=False
        )
        job_ref = ray.put(job)  # once, not once per task
        pending = {remote.remote(job_ref, chunk): chunk for chunk in chunks}
        records: list[EpisodeRecord] = []
        try:
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                for ref in done:
                    batch = _result(ray, ref, pending.pop(ref))
                    records += batch
                    bar.update(len(batch))
        finally:
            for ref in pending:  # after an error or Ctrl-C: nothing more runs for this job
                ray.cancel(ref)
        return records


def _result(ray, ref, chunk: list[Task]) -> list[EpisodeRecord]:
    """The task's records; its failure as the worker's own exception (Ray's wrapper, with the
    remote traceback, chained as the cause), named by the chunk's episodes."""
    shown = ", ".join(str(t[0]) for t in chunk[:8])
    more = f" … ({len(chunk)} in all)" if len(chunk) > 8 else ""
    where = f"in a Ray task flying episodes {shown}{more}"
    try:
        return ray.get(ref)
    except ray.exceptions.RayTaskError as err:
        cause = err.cause
        if not isinstance(cause, Exception):  # the worker's exception did not survive pickling
            err.add_note(where)
            raise
        cause.add_note(where)
        raise cause from err
    except ray.exceptions.WorkerCrashedError as err:
        err.add_note(f"{where}: its worker process died {MAX_RETRIES + 1} times (out of memory?)")
        raise
    except ray.exceptions.RayError as err:
        err.add_note(where)
        raise
