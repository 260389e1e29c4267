"""Fan work out over ``dask.distributed``: one place for datasets (sim) and sweeps (bench).

A task is one item (a sequence to simulate, a sequence to grade); each task
writes its own files atomically and returns a small JSON-able row; the client
collects the rows (the manifest, the results table are the only shared state).

* :func:`dask_client`: a ``LocalCluster`` of ``workers`` single-threaded
  processes by default (numba kernels and numpy hold the GIL in places, so
  processes, not threads), or a client of an existing scheduler
  (``tcp://host:8786``, started by ``dask scheduler`` / ``dask worker``).
* :func:`run_tasks`: submit ``fn(item)`` for every item with ``retries`` (a
  task that raises is retried; a worker that dies is replaced by its nanny and
  its task rescheduled, up to the scheduler's ``allowed-failures``), show a
  tqdm bar over completions, and yield ``(index, result, error)`` in completion
  order: one failing item never stops the others.
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any


class ClusterError(RuntimeError):
    """The scheduler cannot be reached or the cluster cannot start (message names the address)."""


def default_workers() -> int:
    """Workers of the default ``LocalCluster``: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


@contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None, *, client=None,
                memory_limit: str | int = "auto", timeout_s: float = 20.0) -> Iterator[Any]:
    """A ``distributed.Client``: ``client`` itself, an existing ``scheduler``, or a new ``LocalCluster``.

    Parameters
    ----------
    workers : int, optional
        Worker processes of the local cluster (one thread each); default
        :func:`default_workers`. Ignored with ``scheduler`` or ``client``.
    scheduler : str, optional
        Address of a running scheduler (``tcp://10.0.0.5:8786``); its workers
        must import ``evedge`` and see the output folder at the same path.
    client : distributed.Client, optional
        Use this client and leave it open (tests share one cluster).
    memory_limit : str or int
        Per-worker memory limit of the local cluster (dask's ``"auto"``:
        the machine's memory divided among the workers).
    timeout_s : float
        How long to wait for the scheduler.

    Yields
    ------
    distributed.Client

    Raises
    ------
    ClusterError
        The scheduler cannot be reached (its address named), or ``workers`` < 1.

    Examples
    --------
    >>> with dask_client(workers=2) as c:               # doctest: +SKIP
    ...     list(run_tasks(c, abs, [-1, -2], progress=False))
    """
    if client is not None:
        yield client
        return
    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            c = Client(scheduler, timeout=f"{timeout_s}s")
        except (OSError, TimeoutError, ValueError) as err:
            raise ClusterError(f"cannot reach the Dask scheduler at {scheduler!r}: {err}") from None
        try:
            yield c
        finally:
            c.close()
        return
    n = default_workers() if workers is None else workers
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ClusterError(f"workers must be an integer >= 1, got {workers!r}")
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                           memory_limit=memory_limit, silence_logs=logging.ERROR)
    try:
        with Client(cluster) as c:
            yield c
    finally:
        cluster.close()


def run_tasks(client, fn: Callable, items: Sequence, *, retries: int = 2, progress: bool = True,
              desc: str = "tasks", unit: str = "task") -> Iterator[tuple[int, Any, BaseException | None]]:
    """Run ``fn(item)`` on the cluster for every item; yield ``(index, result, error)`` as they finish.

    Parameters
    ----------
    client : distributed.Client
    fn : callable
        A picklable function of one item.
    items : sequence
        Picklable arguments; ``index`` in the output is the position here.
    retries : int
        Extra attempts of a task that raised.
    progress : bool
        A tqdm bar (stderr) over finished tasks.
    desc, unit : str
        Labels of the bar.

    Yields
    ------
    index : int
    result : object or None
        ``fn(items[index])``, None when it failed.
    error : BaseException or None
        Why the task failed after its retries (its own exception, or
        ``KilledWorker`` when its worker died too often).
    """
    from dask.distributed import as_completed
    from tqdm import tqdm

    if not items:
        return
    futures = client.map(fn, list(items), retries=retries, pure=False)
    where = {f.key: i for i, f in enumerate(futures)}
    try:
        with tqdm(total=len(futures), desc=desc, unit=unit, disable=not progress, file=sys.stderr) as bar:
            for fut in as_completed(futures):
                try:
                    result, error = fut.result(), None
                except Exception as err:  # the task's own error, or KilledWorker
                    result, error = None, err
                bar.update(1)
                i = where[fut.key]
                fut.release()
                yield i, result, error
    finally:
        for f in futures:  # an interrupted run cancels what is left
            if not f.done():
                f.cancel()
