"""The exit statuses of ``auv-cosim`` (docs/commands.md, "Exit status and errors").

- :data:`OK` (0): everything asked ran; for ``campaign`` and ``envelope``: every point ran.
- :data:`INCOMPLETE` (1): ``campaign`` only: runs not done (a lost worker or scheduler:
  rerun the same command to do them) or the numpy engine disagreeing with the FMUs.
- :data:`USAGE` (2): bad input, an impossible design, an FMU that refuses a call, a bug of
  ours (one line naming the problem; :mod:`orchestrator.cli.errors`).
- :data:`POINTS_FAILED` (3): ``campaign`` or ``envelope`` finished, but some points (or all)
  could not run: their error rows (campaign) or ``failed`` entries (envelope) say why, and
  one line on stderr counts them (:func:`points_failed_line`).
- 130 / 143: stopped by SIGINT / SIGTERM (:data:`orchestrator.interrupt.EXIT_STATUS`); what
  was simulated is kept.

A campaign stopped by a signal exits 130 / 143 whatever its rows; one with runs not done
exits 1; otherwise one with failed points exits 3.
"""
from __future__ import annotations

__all__ = ["INCOMPLETE", "OK", "POINTS_FAILED", "USAGE", "points_failed_line"]

OK = 0
INCOMPLETE = 1
USAGE = 2
POINTS_FAILED = 3


def points_failed_line(command: str, failed: int, total: int, where: str,
                       first: str | None = None) -> str:
    """The one stderr line of a ``campaign`` or ``envelope`` with failed points.

    Parameters
    ----------
    command : str
        ``campaign`` or ``envelope``.
    failed, total : int
        Points that failed, points in all.
    where : str
        Where each failed point's reason is, e.g. "error rows in out/x/results.parquet".
    first : str, optional
        The first failed point's reason (cut to 300 characters).

    Returns
    -------
    str
        ``auv-cosim campaign: 3 of 12 points failed (error rows in ...); first: ...``.
    """
    line = f"auv-cosim {command}: {failed} of {total} points failed ({where})"
    if first:
        text = " ".join(first.split())
        line += f"; the first: {text if len(text) <= 300 else text[:297] + '...'}"
    return line
