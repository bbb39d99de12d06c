"""Where a command's time goes: seconds per phase, each counted once.

A run spends its time building FMUs, solving designs, predicting, instantiating the FMUs,
stepping the loop, computing statistics and recording. The phases nest (building a fleet's
FMUs solves every vehicle's design; a run prepares its design before its loop), so the
clock keeps a stack and counts a phase's *own* time: what a nested phase or a measured part
(:func:`add`, e.g. the loop's seconds inside a run) took is counted there and not again in
the phase around it. ``summary.json``'s ``timing.phases_s`` holds the split of one command
(:func:`split`); ``auv-cosim bench --phases`` prints it.

One clock per process (the phases of seeds run in worker processes are not in it).
"""
from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["PHASES", "add", "phase", "reset", "split"]

#: the phases, in the order a run meets them (``other``: the rest of the command's time)
PHASES = ("build", "design", "predictions", "instantiate", "loop", "statistics",
          "recording", "other")

_own: dict[str, float] = {}
#: open phases: [name, start, seconds of nested phases]
_stack: list[list] = []


def reset() -> None:
    """Forget every phase counted so far (a command starts its clock)."""
    _own.clear()
    _stack.clear()


@contextmanager
def phase(name: str) -> Iterator[None]:
    """Count the time inside the block to ``name``, less what nested phases took.

    Parameters
    ----------
    name : str
        One of :data:`PHASES` (but ``other``).
    """
    frame = [name, time.perf_counter(), 0.0]
    _stack.append(frame)
    try:
        yield
    finally:
        _stack.pop()
        elapsed = time.perf_counter() - frame[1]
        _own[name] = _own.get(name, 0.0) + elapsed - frame[2]
        if _stack:
            _stack[-1][2] += elapsed


def add(name: str, seconds: float) -> None:
    """Count ``seconds`` measured inside the current phase to ``name`` instead.

    Parameters
    ----------
    name : str
        The part's phase (``loop``: the seconds the master's loop reports).
    seconds : float
        Its duration, s.
    """
    _own[name] = _own.get(name, 0.0) + float(seconds)
    if _stack:
        _stack[-1][2] += float(seconds)


def split(total_s: float) -> dict[str, float]:
    """Seconds per phase of :data:`PHASES` (0 for those not met), ``other`` the rest of
    ``total_s``.

    Parameters
    ----------
    total_s : float
        The command's time so far, s.

    Returns
    -------
    dict[str, float]
        Phase -> seconds; they sum to ``total_s`` (``other`` may be slightly negative if
        ``total_s`` was measured from later than the first phase).
    """
    out = {p: _own.get(p, 0.0) for p in PHASES if p != "other"}
    out["other"] = total_s - sum(out.values())
    return out
