"""What every local Dask worker process runs first (a Dask preload,
:func:`orchestrator.campaign.cluster.dask_client`): the worker ignores SIGINT.

Ctrl-C in a terminal reaches every process of the foreground group: the command and the
local cluster's workers. The command stops the campaign itself (it cancels what is left,
keeps every finished row, closes the cluster: :mod:`.runner`); a worker that took the
signal as well would die with asyncio's KeyboardInterrupt traceback on standard error
before the command's one line. SIGTERM is left as it is: it is how the cluster ends its
workers.
"""
from __future__ import annotations

import signal
import threading
from typing import Any

__all__ = ["dask_setup"]


def dask_setup(worker: Any = None) -> None:
    """Ignore SIGINT in this worker process (Dask calls it when the worker starts).

    Parameters
    ----------
    worker : distributed.Worker, optional
        The worker (unused).
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
