"""What the default blueprint needs of a whole run, kept as the run's chunks come
(:class:`RunSummary`): per trace column its extremes, and for the paper layout the traces
themselves up to :data:`SAMPLE_ROWS` steps, then every 2nd, 4th, ... step (by global step, so
the same whatever the chunks)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .chunks import RecordedChunk

__all__ = ["SAMPLE_ROWS", "RunSummary"]

#: steps of every trace kept whole for the paper layout's blueprint; beyond, every 2nd,
#: 4th, ... step (by global step, so the same whatever the chunks)
SAMPLE_ROWS = 1 << 15


class RunSummary:
    """What the blueprint needs of one method's traces, kept as they come: per column the
    minimum and maximum (NaN if any value is) and the minimum and maximum of the finite
    values; with ``sample``, the rows of every ``every``-th step (global), ``every``
    doubling while more than :data:`SAMPLE_ROWS` are kept."""

    def __init__(self, sample: bool) -> None:
        self.sample = sample
        self.every = 1
        self.ext: dict[str, list[np.ndarray]] = {}          # pmin, pmax, fmin, fmax, finite
        self.rows: dict[str, list[np.ndarray]] = {}
        self.ks: list[np.ndarray] = []
        self.leader: list[np.ndarray] = []                   # leader (min, max), fleets

    def add(self, chunk: RecordedChunk) -> None:
        """A chunk's digest (:func:`.chunks.digest`): its extremes, its leader's, and with
        ``sample`` its rows of every step."""
        for key, new in chunk.extremes.items():
            old = self.ext.get(key)
            self.ext[key] = new if old is None else [
                np.minimum(old[0], new[0]), np.maximum(old[1], new[1]),
                np.minimum(old[2], new[2]), np.maximum(old[3], new[3]), old[4] | new[4]]
        if chunk.leader is not None:
            self.add_leader(chunk.leader)
        if not self.sample or chunk.every is None:
            return
        traces = chunk.every
        ks = np.arange(chunk.k0, chunk.k0 + chunk.steps, dtype=np.int64)
        keep = ks % self.every == 0
        self.ks.append(ks[keep])
        for key, a in traces.items():
            self.rows.setdefault(key, []).append(a[keep])
        while sum(k.size for k in self.ks) > SAMPLE_ROWS:
            self.every *= 2
            ks = np.concatenate(self.ks)
            keep = ks % self.every == 0
            self.ks = [ks[keep]]
            self.rows = {key: [np.concatenate(v)[keep]] for key, v in self.rows.items()}

    def add_leader(self, new: list[np.ndarray]) -> None:
        """The leader position's [minimum, maximum] over a chunk."""
        self.leader = new if not self.leader else [np.minimum(self.leader[0], new[0]),
                                                   np.maximum(self.leader[1], new[1])]

    def extremes(self, key: str) -> np.ndarray:
        """(4, dim): minimum, maximum, finite minimum, finite maximum (a column without a
        finite value: its minimum and maximum), so that ``np.min``/``np.max`` and the finite
        extremes of this array are those of the whole column."""
        pmin, pmax, fmin, fmax, finite = self.ext[key]
        return np.vstack([pmin, pmax, np.where(finite, fmin, pmin), np.where(finite, fmax, pmax)])

    def compact(self) -> dict[str, np.ndarray]:
        """Stand-ins for the whole traces: the traces themselves while every step is kept,
        else the kept rows and the extremes."""
        out = {}
        for key in self.ext:
            if self.sample and self.every == 1:
                out[key] = np.concatenate(self.rows[key])
            elif self.sample:
                out[key] = np.vstack([np.concatenate(self.rows[key]), self.extremes(key)])
            else:
                out[key] = self.extremes(key)
        return out
