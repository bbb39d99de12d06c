"""Stop a long run between steps on SIGINT or SIGTERM, keeping what it simulated.

:func:`stop_on_signals` installs handlers that only set a :class:`StopFlag`; the master
checks it between chunks of steps (:func:`orchestrator.cosim.master.run_system`; the
compiled master before every step) and returns the traces simulated so far. No
exception is raised inside FMU code (a KeyboardInterrupt raised in a pythonfmu slave turns
into fmi2Fatal). A second signal while stopping restores the default handlers and raises
KeyboardInterrupt (a hard stop).
"""
from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

__all__ = ["StopFlag", "stop_on_signals", "EXIT_STATUS"]

#: exit status of a command stopped by a signal (by its name): 128 + the signal number
EXIT_STATUS = {s.name: 128 + s.value for s in (signal.SIGINT, signal.SIGTERM)}


class StopFlag:
    """Set by a signal handler; true once a stop was requested."""

    def __init__(self) -> None:
        self.signum: int | None = None

    def __bool__(self) -> bool:
        return self.signum is not None

    @property
    def name(self) -> str | None:
        """The signal's name (``SIGINT``), or None."""
        return None if self.signum is None else signal.Signals(self.signum).name


@contextmanager
def stop_on_signals(flag: StopFlag | None = None) -> Iterator[StopFlag]:
    """Within the block, SIGINT and SIGTERM set the returned flag instead of stopping the
    process (main thread only; elsewhere the flag is returned and never set).

    Parameters
    ----------
    flag : StopFlag, optional
        The flag to set (default: a new one).

    Yields
    ------
    StopFlag
    """
    flag = flag or StopFlag()
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return
    signals = (signal.SIGINT, signal.SIGTERM)

    def handler(signum: int, frame: FrameType | None) -> None:
        if flag:                                  # the second one: stop now
            for s, h in old.items():
                signal.signal(s, h)
            raise KeyboardInterrupt
        flag.signum = signum

    old = {s: signal.signal(s, handler) for s in signals}
    try:
        yield flag
    finally:
        for s, h in old.items():
            signal.signal(s, h)
