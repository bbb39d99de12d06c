"""Stop a long run on SIGINT or SIGTERM, keeping what it simulated.

:func:`stop_on_signals` installs handlers that set a :class:`StopFlag`; the master checks
it between chunks of steps (:func:`orchestrator.cosim.master.run_system`; the compiled
master before every step) and returns the traces simulated so far. No exception is raised
inside FMU code (a KeyboardInterrupt raised in a pythonfmu slave turns into fmi2Fatal).
A second signal while stopping restores the default handlers and raises
KeyboardInterrupt (a hard stop).

The phases before the first step (the stacked design, the predictions: numpy and LAPACK
calls that can take minutes) run inside :func:`interruptible`: there a signal raises
:class:`Interrupted` at once, that is as soon as the LAPACK call in progress returns (a
call cannot be stopped midway), and the command ends with one line naming the signal and
the phase (:func:`orchestrator.cli.errors.run_command`), exit status 128 + the signal.
Only the main thread's blocks count: code in other threads (a Dask worker's tasks) and
FMU code outside such a block never see the exception; and only until a loop has run in
the process (:func:`mark_simulated`): a stop after that waits for the next loop, which
keeps and writes what was simulated (an earlier method, grid point or plant).
"""
from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

__all__ = ["EXIT_STATUS", "Interrupted", "StopFlag", "interruptible", "mark_simulated",
           "stop_on_signals"]

#: exit status of a command stopped by a signal (by its name): 128 + the signal number
EXIT_STATUS = {s.name: 128 + s.value for s in (signal.SIGINT, signal.SIGTERM)}

#: the flags of the open stop_on_signals blocks (innermost last) and the phases of the
#: open interruptible blocks of the main thread (innermost last)
_FLAGS: list[StopFlag] = []
_PHASES: list[str] = []
#: whether a co-simulation loop has started in this process (mark_simulated)
_SIMULATED: list[bool] = [False]


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


class Interrupted(KeyboardInterrupt):
    """A stop requested during a phase before the first step (:func:`interruptible`).

    Attributes
    ----------
    signal : str
        The signal's name (``SIGTERM``).
    phase : str
        What was being done, e.g. "the stacked design of 80 vehicles (726 states)".
    """

    def __init__(self, signal_name: str, phase: str):
        super().__init__(signal_name, phase)
        self.signal = signal_name
        self.phase = phase

    def __str__(self) -> str:
        return (f"interrupted by {self.signal} during {self.phase}, before the first step: "
                "nothing was simulated")


def mark_simulated() -> None:
    """Note that a co-simulation loop starts in this process: from then on a stop no
    longer cuts a phase short (:func:`interruptible` is a plain block), so what was
    simulated (an earlier method, grid point or plant of the same command) is kept and
    written; the command stops between steps instead."""
    _SIMULATED[0] = True


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextmanager
def stop_on_signals(flag: StopFlag | None = None) -> Iterator[StopFlag]:
    """Within the block, SIGINT and SIGTERM set the returned flag instead of stopping the
    process (main thread only; elsewhere the flag is returned and never set); inside an
    :func:`interruptible` block they also raise :class:`Interrupted`.

    Parameters
    ----------
    flag : StopFlag, optional
        The flag to set (default: a new one).

    Yields
    ------
    StopFlag
    """
    flag = flag or StopFlag()
    if not _main_thread():
        yield flag
        return
    signals = (signal.SIGINT, signal.SIGTERM)

    def handler(signum: int, frame: FrameType | None) -> None:
        if flag:                                  # the second one: stop now
            for s, h in old.items():
                signal.signal(s, h)
            raise KeyboardInterrupt
        flag.signum = signum
        if _PHASES:                               # a phase before the first step: stop it
            raise Interrupted(str(flag.name), _PHASES[-1])

    old = {s: signal.signal(s, handler) for s in signals}
    _FLAGS.append(flag)
    try:
        yield flag
    finally:
        _FLAGS.remove(flag)
        for s, h in old.items():
            signal.signal(s, h)


@contextmanager
def interruptible(phase: str) -> Iterator[None]:
    """A phase of pure computation (numpy, scipy) that a stop may cut short: within the
    block, under :func:`stop_on_signals` in the main thread, SIGINT or SIGTERM raises
    :class:`Interrupted` as soon as the call in progress returns; a stop already requested
    raises it on entry. Elsewhere (another thread, no stop_on_signals, or once a loop has
    run in this process: :func:`mark_simulated`) the block is plain.

    Parameters
    ----------
    phase : str
        What the block does, for the message ("the stacked design of ...").

    Raises
    ------
    Interrupted
        When a stop is requested before or during the block.
    """
    if not _main_thread() or not _FLAGS or _SIMULATED[0]:
        yield
        return
    flag = _FLAGS[-1]
    if flag:
        raise Interrupted(str(flag.name), phase)
    _PHASES.append(phase)
    try:
        yield
    finally:
        _PHASES.pop()
