"""``compare``'s seeds on local worker processes.

The first seed of each method runs in the command's own process (its traces go to the
.rrd); the other seeds run meanwhile in a pool of worker processes (``spawn``: a fresh
interpreter, no copied FMU libraries; one BLAS thread, as in the parent), each a whole
co-simulation of the same FMUs through the same run step
(:meth:`orchestrator.running.setup.RunSetup.run`: any deployment, links, vehicle model and
FMU kind), returning only its statistics. A seed's result does not
depend on where it ran (one BLAS thread everywhere, its own noise stream), so the summary
is the serial one. Workers ignore SIGINT: the command stops them (pending seeds cancelled,
the running ones finish) when it is interrupted.

Only worth it when the seeds left are long enough to pay for starting the workers (about
1 s each): :func:`seed_pool` returns None below ``MIN_PARALLEL_STEPS`` steps of work.
"""
from __future__ import annotations

import os
import signal
from collections.abc import Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any

__all__ = ["seed_pool", "seed_stats", "MIN_PARALLEL_STEPS"]

#: below this many co-simulation steps in the seeds after the first, run serially
MIN_PARALLEL_STEPS = 50_000


def _init_worker() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    import orchestrator  # noqa: F401  (one BLAS thread, before numpy)


def seed_stats(setup: Any, method: Any, seed: int, system: Any, k0: int,
               formation: tuple | None = None
               ) -> tuple[dict[str, Any], float, dict[str, tuple[float, int, float]]]:
    """One seed's co-simulation on a worker: its statistics and loop time.

    Parameters
    ----------
    setup : RunSetup
        The command's setup (:mod:`orchestrator.running.setup`), its FMUs already built.
    method : Method
        The method.
    seed : int
    system : SystemDescription
        The system of the method and seed (made in the command's process).
    k0 : int
        First sample of the statistics window.
    formation : tuple or None, optional
        (position_index, offsets, edges, h) of a fleet: the stats then hold ``formation``
        and ``segments``.

    Returns
    -------
    stats : dict[str, Any]
        The run's statistics (:class:`orchestrator.running.statistics.RunStatistics`,
        accumulated as the run goes).
    loop_s : float
        Seconds in the step loop.
    link_ages : dict
        Over acoustic links, per link its age of information over the window (sum, count,
        max, s); else empty.
    """
    from .statistics import RunRecorder, RunStatistics
    recorder = RunRecorder(RunStatistics(setup.sc, k0, formation))
    res = setup.run(method, seed, system=system, recorder=recorder)
    stats = recorder.statistics
    return (stats.result(), res.loop_s,
            stats.link_ages(res.info["links"]) if "links" in res.info else {})


class SeedPool:
    """A process pool for seeds (module docstring); ``submit`` returns a Future."""

    def __init__(self, workers: int):
        import multiprocessing
        self.pool = ProcessPoolExecutor(max_workers=workers, initializer=_init_worker,
                                        mp_context=multiprocessing.get_context("spawn"))

    def submit(self, *args: Any) -> Future:
        """``seed_stats(*args)`` on a worker (started here, with the project's own sys.path:
        :func:`orchestrator.cosim.instance.fmu_free_sys_path`)."""
        from ..cosim.instance import fmu_free_sys_path
        with fmu_free_sys_path():
            return self.pool.submit(seed_stats, *args)

    def close(self) -> None:
        """Cancel what has not started, wait for what runs."""
        self.pool.shutdown(wait=True, cancel_futures=True)


@contextmanager
def seed_pool(steps: int, seeds: int, methods: int,
              workers: int | None = None) -> Iterator[SeedPool | None]:
    """A pool for the seeds after the first of each method for the block (None when not
    worth it: one worker, one seed, or less than ``MIN_PARALLEL_STEPS`` steps left);
    closed at the end of the block (pending seeds cancelled, running ones waited for).

    Parameters
    ----------
    steps : int
        Steps per run.
    seeds : int
        Seeds per method.
    methods : int
        Number of methods.
    workers : int, optional
        Worker processes (default: one per core; 1 means serial).

    Yields
    ------
    SeedPool or None
    """
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count() or 1
    n = workers if workers is not None else cores
    left = (seeds - 1) * methods
    if n <= 1 or left < 1 or left * steps < MIN_PARALLEL_STEPS:
        yield None
        return
    pool = SeedPool(min(n, left))
    try:
        yield pool
    finally:
        pool.close()
