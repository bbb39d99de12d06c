"""A real Dask cluster for the tests: `dask scheduler` and `dask worker` processes on
127.0.0.1 (free ports), one BLAS thread each, stopped with SIGTERM (then SIGKILL)."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

BIN = Path(sys.executable).parent
ENV = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class Cluster:
    address: str
    scheduler: subprocess.Popen
    workers: list[subprocess.Popen] = field(default_factory=list)


@contextmanager
def dask_cluster(n_workers: int = 2, timeout: float = 60.0,
                 worker_env: list[dict[str, str]] | None = None) -> Iterator[Cluster]:
    """Start a scheduler and ``n_workers`` single-threaded workers (worker i with the extra
    environment ``worker_env[i]``, e.g. its own ``OPENBLAS_CORETYPE``); wait until they
    joined."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = subprocess.Popen([BIN / "dask", "scheduler", "--host", "127.0.0.1", "--port",
                                  str(port), "--no-dashboard"], env=ENV,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    cluster = Cluster(address, scheduler)
    try:
        for i in range(n_workers):
            extra = worker_env[i] if worker_env else {}
            cluster.workers.append(subprocess.Popen(
                [BIN / "dask", "worker", address, "--nthreads", "1", "--no-dashboard",
                 "--host", "127.0.0.1"], env={**ENV, **extra},
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from dask.distributed import Client
        deadline = time.monotonic() + timeout
        with Client(address, timeout="30s") as client:
            while len(client.scheduler_info()["workers"]) < n_workers:
                assert time.monotonic() < deadline, "workers did not join"
                time.sleep(0.2)
        yield cluster
    finally:
        procs = [*cluster.workers, cluster.scheduler]
        for p in procs:
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
