"""Pacing a run to the wall clock (``run --realtime FACTOR``), for hardware- and
software-in-the-loop tests: step k of h seconds may end no earlier than

    t_wall(k) = t_start + (k + 1 - k_start) h / FACTOR        (CLOCK_MONOTONIC, s)

(absolute deadlines: waiting never accumulates drift). A step that ends after its deadline
is an *overrun*; the run does not wait then and catches up as the next steps allow. The
count and the worst lateness (s) go to the printout and ``summary.json``'s ``realtime``.
The Python master waits in :meth:`Pacer.after`; the compiled master
(``native_master.c``, the ``Pace`` struct) does the same in C with ``clock_nanosleep``
on the same clock.
"""
from __future__ import annotations

import ctypes
import time
from typing import Any

__all__ = ["Pace", "Pacer"]


class Pace(ctypes.Structure):
    """native_master.c's ``Pace``."""

    _fields_ = [("factor", ctypes.c_double), ("start", ctypes.c_double),
                ("origin", ctypes.c_int64), ("overruns", ctypes.c_int64),
                ("worst", ctypes.c_double)]


class Pacer:
    """The wall-clock deadlines of a run's steps (module docstring).

    Parameters
    ----------
    factor : float
        Simulated seconds per wall-clock second (1: real time; 10: ten times faster).
    h : float
        Communication step, s.
    """

    def __init__(self, factor: float, h: float):
        if not factor > 0:
            raise ValueError(f"real-time factor {factor!r}: give a number > 0")
        self.pace = Pace(float(factor), 0.0, -1, 0, 0.0)
        self.h = float(h)
        self.end: float | None = None           #: when the paced loop ended (monotonic s)

    def begin(self, k: int) -> None:
        """Start the clock at step ``k`` (once: a run's later chunks keep the origin)."""
        if self.pace.origin < 0:
            self.pace.start, self.pace.origin = time.monotonic(), int(k)

    def after(self, k: int) -> None:
        """Step ``k`` has ended: wait for its deadline, or count the overrun."""
        p = self.pace
        deadline = p.start + (k + 1 - p.origin) * self.h / p.factor
        late = time.monotonic() - deadline
        if late > 0.0:
            p.overruns += 1
            p.worst = max(p.worst, late)
            return
        while True:                         # sleep() may wake early on a signal
            left = deadline - time.monotonic()
            if left <= 0:
                return
            time.sleep(left)

    def finish(self) -> None:
        """The paced loop has ended (its wall-clock time is measured to here)."""
        self.end = time.monotonic()

    def report(self, steps: int) -> dict[str, Any]:
        """``factor``, ``overruns`` (steps that ended late), ``worst_lateness_s`` and the
        wall-clock seconds the paced steps took against the planned (``wall_s``,
        ``planned_s``)."""
        p = self.pace
        ran = max(0, steps - max(p.origin, 0))
        return {"factor": p.factor, "overruns": int(p.overruns),
                "worst_lateness_s": float(p.worst),
                "wall_s": ((self.end or time.monotonic()) - p.start) if p.origin >= 0 else 0.0,
                "planned_s": ran * self.h / p.factor}
