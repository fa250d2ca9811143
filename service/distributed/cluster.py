"""The Dask cluster a run uses, and the one loop that sends it batches.

``open_client(workers=N)`` starts an embedded ``LocalCluster`` of N worker processes (one
thread each: the compiled physics holds the GIL); ``open_client(scheduler=ADDRESS)``
joins a running cluster (``dask scheduler`` and ``dask worker``, docs/deployment.md).
Either way the workers get ``tasks.WarmUp``: the physics loaded from numba's cache (and
the site's diagnoser built) once per worker, before its first task, and again on a
worker that Dask restarts.

``run_batches`` keeps a bounded number of batches in flight (their inputs travel with
them, so the scheduler never holds the whole archive) and hands each result back as it
completes. A worker lost mid-batch (killed, out of memory) is Dask's to handle: the
scheduler gives the batch to another worker (up to ``distributed.scheduler.allowed-failures``
times), and the caller stores each batch's results once, keyed, so a retry stores nothing
twice.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from distributed import Client

T = TypeVar("T")
R = TypeVar("R")

IN_FLIGHT_PER_WORKER = 3
"""Batches queued per worker: enough to keep it busy, few enough to bound memory."""


class ClusterError(RuntimeError):
    """The cluster cannot be reached or started (one line: which and why)."""


@dataclass(frozen=True)
class ClusterInfo:
    workers: int
    address: str
    embedded: bool


@contextmanager
def open_client(
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    timeout: float = 10.0,
    warm: Any = None,
) -> Iterator[tuple[Client, ClusterInfo]]:
    """A Dask client on an embedded LocalCluster of ``workers`` processes, or on the
    cluster at ``scheduler``; ``warm``: a worker plugin registered on every worker."""
    from distributed import Client, LocalCluster

    cluster = None
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise ClusterError(
                f"cannot reach the Dask scheduler at {scheduler} within {timeout:g} s: {reason}"
            ) from None
    else:
        n = workers if workers is not None else max(1, os.cpu_count() or 1)
        try:
            cluster = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
        except Exception as exc:
            raise ClusterError(f"cannot start a local Dask cluster of {n} workers: {exc}") from exc
        client = Client(cluster, set_as_default=False)
    try:
        if warm is not None:
            client.register_plugin(warm)
        count = len(client.scheduler_info(n_workers=-1)["workers"])
        if count == 0:
            client.wait_for_workers(1, timeout=timeout)
            count = len(client.scheduler_info(n_workers=-1)["workers"])
        yield client, ClusterInfo(count, str(client.scheduler.address), cluster is not None)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def run_batches(
    client: Client,
    fn: Callable[..., R],
    batches: Iterable[T],
    *args: Any,
    in_flight: int,
) -> Iterator[tuple[T, R]]:
    """``fn(batch, *args)`` on the cluster for every batch, at most ``in_flight`` at once;
    yields (batch, result) as each completes (any order). A batch whose task raised
    re-raises here."""
    from distributed import as_completed

    todo = iter(batches)
    pending: dict[Any, T] = {}

    def submit() -> Any:
        batch = next(todo, None)
        if batch is None:
            return None
        future = client.submit(fn, batch, *args, pure=False)
        pending[future.key] = batch
        return future

    first = [f for f in (submit() for _ in range(max(1, in_flight))) if f is not None]
    if not first:
        return
    done = as_completed(first, loop=client.loop)
    for future in done:
        batch = pending.pop(future.key)
        result = future.result()
        future.release()
        nxt = submit()
        if nxt is not None:
            done.add(nxt)
        yield batch, result
