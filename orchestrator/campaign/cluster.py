"""Where a campaign's tasks run: a Dask ``LocalCluster`` or an existing Dask cluster.

The only module of the package that imports Dask (the commands that do not use it never
pay for importing it).

Local: one worker process per core (``--workers N`` to choose), each single-threaded, with
one BLAS thread set in the worker's environment (``OPENBLAS_NUM_THREADS`` /
``OMP_NUM_THREADS`` / ``MKL_NUM_THREADS`` = 1) before numpy loads: the co-simulation's small
products run fastest on one thread, and the thread count changes the last bits of a
result (the same seed gives the same row only with the same count). No dashboard. Each
worker ignores SIGINT (:mod:`.worker_setup`): Ctrl-C, which reaches the workers too, stops
the campaign through the command alone, without a worker's traceback.

Remote (``--scheduler tcp://host:port``): ``Client(address)``; each worker needs this
package and its dependencies installed (the same versions: they are in the run keys),
started with ``dask worker tcp://host:port --nworkers N --nthreads 1`` (importing the
package applies one BLAS thread there too, see :mod:`orchestrator`).
"""
from __future__ import annotations

import logging
import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from .spec import SpecError

__all__ = ["dask_client", "BLAS_ENV", "WORKER_SETUP", "worker_count"]

#: set in every local worker's environment
BLAS_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
#: run first by every local worker: it ignores SIGINT (Ctrl-C stops the campaign through
#: the command, with no worker traceback: :mod:`.worker_setup`)
WORKER_SETUP = "orchestrator.campaign.worker_setup"


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:                # not on Linux
        return os.cpu_count() or 1


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None,
                connect_timeout: float = 20.0) -> Iterator[Any]:
    """A ``distributed.Client``: of a new local cluster, or connected to ``scheduler``.

    Parameters
    ----------
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:port``).
    workers : int, optional
        Worker processes of the local cluster (default: one per core).
    connect_timeout : float, optional
        Seconds to wait for the scheduler, s.

    Yields
    ------
    distributed.Client

    Raises
    ------
    SpecError
        If the scheduler cannot be reached (one line naming it).
    """
    from dask.distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout=f"{connect_timeout}s")
        except (OSError, TimeoutError) as exc:
            raise SpecError(f"cannot reach the Dask scheduler at {scheduler}: "
                            f"{' '.join(str(exc).split())}") from None
        try:
            yield client
        finally:
            client.close(timeout=5)
        return
    from ..cosim.instance import fmu_free_sys_path
    n = workers or _cores()
    with fmu_free_sys_path():         # the workers import the project, not an FMU's copy
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               # CRITICAL: a worker's heartbeat to a scheduler that an
                               # interrupt closed first logs an ERROR with a traceback;
                               # what fails in a task reaches its row (tasks.py) instead
                               dashboard_address=None, silence_logs=logging.CRITICAL,
                               env=dict(BLAS_ENV), host="127.0.0.1",
                               preload=[WORKER_SETUP])
    client = Client(cluster)
    try:
        yield client
    finally:
        try:
            client.close(timeout=5)
        finally:
            cluster.close(timeout=10)


def worker_count(client: Any) -> int:
    """Number of workers the scheduler knows now (at least 1).

    Parameters
    ----------
    client : distributed.Client

    Returns
    -------
    int
    """
    try:
        return max(1, len(client.scheduler_info()["workers"]))
    except Exception:
        return 1
