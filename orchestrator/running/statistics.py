"""The statistics of one run, accumulated chunk by chunk of its stacked traces as the run
goes (:class:`RunStatistics`), and what a run keeps and sends on, chunk by chunk
(:class:`RunRecorder`, the master's :class:`~orchestrator.cosim.master.TraceSink` through
:meth:`orchestrator.running.setup.RunSetup.run`).

The figures are those of :mod:`orchestrator.analysis.summary` (RMS values, cost rate),
:mod:`orchestrator.analysis.formation` (each edge's formation error, the closest approach)
and :mod:`orchestrator.analysis.tracking_segments` (straight legs and turns, saturation),
and per acoustic link the age of information (mean and max over the window): sums, counts
and extremes, so that memory does not grow with the horizon. A run in one chunk gives the
whole-trace figures exactly; in several, the same maxima, counts and closest approach and
the sums to rounding. The chunk length is a function of the system alone
(:func:`chunk_steps`): the same run gives the same figures, bit for bit, on any machine.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from ..analysis import tracking_segments as segments
from ..analysis.formation import FormationSums
from ..analysis.summary import TraceSums

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["CHUNK_BYTES", "MAX_CHUNK_STEPS", "MIN_CHUNK_STEPS", "RunRecorder", "RunStatistics",
           "chunk_steps"]

#: bytes of one chunk of a run's trace buffers (the master's, and each copy made of a
#: chunk: the stacked layout, what goes to the .rrd writer)
CHUNK_BYTES = 64 * 2 ** 20
#: the fewest steps in a chunk
MIN_CHUNK_STEPS = 64
#: the most steps in a chunk (checkpoints fall between chunks: a few seconds of a small
#: system's run)
MAX_CHUNK_STEPS = 2 ** 14


def chunk_steps(width: int) -> int:
    """Steps per chunk of a system of ``width`` values per step: the largest power of two
    whose chunk stays within :data:`CHUNK_BYTES`, between :data:`MIN_CHUNK_STEPS` and
    :data:`MAX_CHUNK_STEPS`."""
    rows = CHUNK_BYTES // (8 * max(1, int(width)))
    return min(MAX_CHUNK_STEPS,
               max(MIN_CHUNK_STEPS, 1 << max(0, int(rows).bit_length() - 1)))


class RunStatistics:
    """One run's statistics (module docstring), fed chunk by chunk (:meth:`add`).

    Parameters
    ----------
    sc : Scenario
        Its Q, R; for a fleet the leader (turns) and the controllers' force limit.
    k0 : int
        First sample of the statistics window.
    formation : tuple or None
        (position_index, offsets, edges, h) of a fleet
        (:func:`orchestrator.running.setup.stats_context`), None for a single system.
    """

    def __init__(self, sc: Scenario, k0: int, formation: tuple | None):
        self.k0 = int(k0)
        self.trace = TraceSums(sc.system.Q, sc.system.R)
        self.formation = self.segments = None
        if formation is not None:
            index, offsets, edges, h = formation
            self.formation = FormationSums(index, offsets, edges, k0, h)
            self.segments = segments.SegmentSums()
            leader = sc.fleet["leader"]
            self.F, self.H = (np.asarray(leader[k], float) for k in ("F", "H"))
            self.u_max = (sc.design.u_max if sc.design is not None and sc.design.clip
                          else None)
        #: per link column of ``link_age``: [sum, count, max] over the window, s
        self.ages: list[list[float]] = []

    def add(self, start: int, traces: Mapping[str, np.ndarray]) -> None:
        """Samples start .. start + rows - 1 of the run's stacked traces."""
        w = max(0, self.k0 - start)                  # the chunk's first window row
        e = traces["e"]
        self.trace.add(e[w:], traces["u"][w:])
        if self.formation is not None:
            self.formation.add(start, traces["x"])
            sat = traces.get("saturated")
            if self.u_max is not None:                   # the controllers' force limit
                sat = segments.force_saturation(traces["u"], self.u_max, sat)
            turning = (np.abs(segments.leader_turn_rate(traces["z"], self.F, self.H))
                       > segments.TURN_RATE)
            self.segments.add(e[w:], turning[w:], None if sat is None else sat[w:])
        ages = traces.get("link_age")
        if ages is not None and ages.shape[0] > w:
            win = np.asarray(ages[w:], float)
            if not self.ages:
                self.ages = [[0.0, 0, -np.inf] for _ in range(win.shape[1])]
            for c, acc in enumerate(self.ages):
                acc[0] += np.sum(win[:, c])
                acc[1] += win.shape[0]
                acc[2] = max(acc[2], float(np.max(win[:, c])))

    def result(self) -> dict[str, Any]:
        """The statistics as the summary and the campaign rows hold them: ``rms_e``,
        ``mean_e``, ``rms_u``, ``cost_rate``; for a fleet ``formation`` and ``segments``."""
        stats = self.trace.result()
        if self.formation is not None:
            stats["formation"] = self.formation.result()
            stats["segments"] = self.segments.result()
        return stats

    def link_ages(self, links: list[str]) -> dict[str, tuple[float, int, float]]:
        """Per link ("j -> i", the columns' order) its age of information over the window:
        (sum, count, max), s."""
        return {name: (float(s), int(n), float(m)) for name, (s, n, m) in zip(links, self.ages)}


class RunRecorder:
    """What a run does with its stacked traces as they come, chunk by chunk: the
    statistics (:class:`RunStatistics`), the chunks sent to a ``.rrd`` stream
    (``stream.send(name, k0, traces)``), the traces kept in memory (``keep``: every step;
    for a caller that wants them whole). ``chunk``: steps per chunk (default: from the
    system, :func:`chunk_steps`)."""

    def __init__(self, statistics: RunStatistics | None = None, *, stream: Any = None,
                 name: str = "", keep: bool = False, chunk: int | None = None):
        self.statistics = statistics
        self.stream, self.name, self.keep = stream, name, keep
        self.kept: dict[str, np.ndarray] = {}
        #: steps per chunk (None: the run sets it from its system's width,
        #: :func:`chunk_steps`) and the steps the run plans (set by the run)
        self.chunk_steps, self.planned = chunk, 0
        self.steps = 0                                   #: steps taken so far

    def take(self, k0: int, traces: Mapping[str, np.ndarray]) -> None:
        """Rows k0 .. k0 + n - 1 of the run's stacked traces (views the next chunk may
        overwrite: what is kept is copied)."""
        if self.statistics is not None:
            self.statistics.add(k0, traces)
        if self.stream is not None:
            self.stream.send(self.name, k0, traces)
        rows = len(next(iter(traces.values())))
        if self.keep:
            for k, v in traces.items():
                have = self.kept.get(k)
                if have is None or have.shape[0] < k0 + rows:
                    grown = np.empty((max(self.planned, k0 + rows),) + v.shape[1:], v.dtype)
                    if have is not None:
                        grown[:self.steps] = have[:self.steps]
                    self.kept[k] = have = grown
                have[k0:k0 + rows] = v
        self.steps = k0 + rows

    def traces(self) -> dict[str, np.ndarray]:
        """The kept traces (``keep``): every step taken."""
        return {k: v[:self.steps] for k, v in self.kept.items()}

    def __getstate__(self) -> dict[str, Any]:
        """What a checkpoint holds: the statistics, the steps taken, the kept traces up to
        there (not the stream: it is saved by its own position)."""
        state = dict(self.__dict__)
        state["kept"] = self.traces()
        state["stream"] = None
        return state
