"""A chunk of a run's traces reduced to what its recording keeps (:func:`digest`): the
recorded rows of the recorded outputs and, over every step, what the default blueprint
needs (each column's extremes, the leader's; the paper layout's samples).

The reduction runs where the traces are, before they go anywhere: a stream in the writer
child (:class:`~orchestrator.recording.background.ChildStream`) gets the digest, not the
full-rate chunk (a fleet recorded at 1 Hz of a 100 Hz loop sends a hundredth of its rows
and only the outputs chosen with ``record``). Samples are chosen by global step, so the
digest of a run does not depend on how it was cut into chunks.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .scene import leader_position
from .selection import LINK_KEYS, Selection
from .validation import _validate
from .writer import _ACTUATOR_KEYS

__all__ = ["ChunkSpec", "RecordedChunk", "clean_chunk", "column_extremes", "digest", "shapes",
           "spec_of"]


@dataclass(frozen=True)
class ChunkSpec:
    """What a stream keeps of a chunk (its validated arguments)."""

    keys: tuple[str, ...]                   #: the layout's trace keys (each chunk has them)
    h: float                                #: step, s
    stride: int                             #: steps between two recorded ones
    selection: Selection                    #: the recorded groups
    leader_output: np.ndarray | None        #: (3, l) of a fleet: leader position = L z

    @property
    def sample(self) -> bool:
        """The paper layout: its blueprint samples every step (:mod:`.summary`)."""
        return not self.selection.fleet


@dataclass
class RecordedChunk:
    """Steps k0 .. k0 + steps - 1 of one method, reduced (:func:`digest`)."""

    method: str
    k0: int
    steps: int
    dims: dict[str, int]                    #: columns of every trace key of the chunk
    ks: np.ndarray                          #: the recorded steps (k % stride == 0)
    rows: dict[str, np.ndarray]             #: the recorded keys' rows at ``ks``
    #: per recorded key over every step: [min, max, finite min, finite max, any finite]
    extremes: dict[str, list[np.ndarray]]
    leader: list[np.ndarray] | None         #: the leader position's [min, max] (fleets)
    every: dict[str, np.ndarray] | None     #: every step's rows (the paper layout)


def column_extremes(a: np.ndarray) -> list[np.ndarray]:
    """Per column of ``a`` (rows, dim): minimum and maximum (NaN if any value is), the
    minimum and maximum of the finite values (+inf / -inf without one), any value finite."""
    lo, hi = a.min(axis=0), a.max(axis=0)
    if np.isfinite(lo).all() and np.isfinite(hi).all():     # every value finite: no masks
        return [lo, hi, lo, hi, np.ones(a.shape[1], dtype=bool)]
    fin = np.isfinite(a)
    return [lo, hi, np.where(fin, a, np.inf).min(axis=0), np.where(fin, a, -np.inf).max(axis=0),
            fin.any(axis=0)]


def clean_chunk(keys: Sequence[str], h: float, method: str, traces: Mapping[str, Any],
                with_links: bool) -> dict[str, np.ndarray] | None:
    """The chunk's traces as float64 (the layout's keys, the actuator keys present, the
    link keys if ``with_links``), checked; None for a chunk of no steps."""
    if isinstance(traces, Mapping):
        first = traces.get(keys[0])
        if first is not None and np.ndim(first) == 2 and np.shape(first)[0] == 0:
            return None
    clean = _validate({method: traces}, h, keys)[0][method]
    steps = clean[keys[0]].shape[0]
    extra = [k for k in _ACTUATOR_KEYS if k in traces]
    if with_links:
        missing = [k for k in LINK_KEYS if k not in traces]
        if missing:
            raise ValueError(f"write_rrd: run {method!r} over links is missing trace "
                             f"key(s) {', '.join(map(repr, missing))}")
        extra += list(LINK_KEYS)
    for key in extra:
        arr = np.asarray(traces[key], dtype=np.float64)
        if arr.ndim != 2 or arr.shape[0] != steps:
            raise ValueError(f"write_rrd: run {method!r} trace {key!r} has shape "
                             f"{arr.shape}, expected ({steps}, ...)")
        clean[key] = arr
    return clean


def digest(spec: ChunkSpec, method: str, k0: int, traces: Mapping[str, object],
           with_links: bool) -> RecordedChunk | None:
    """The chunk's traces checked (:func:`clean_chunk`: the layout's keys,
    the actuator keys present, the link keys with ``with_links``) and reduced to what the
    recording keeps; None for a chunk of no steps.

    Parameters
    ----------
    spec : ChunkSpec
        The stream's layout, stride and selection.
    method : str
        The run's method.
    k0 : int
        Global step of the chunk's first row.
    traces : Mapping
        Trace key -> (steps, dim) array.
    with_links : bool
        The method runs over acoustic links (its ``link_*`` traces are checked).

    Returns
    -------
    RecordedChunk or None
        The rows are views of ``traces`` (copy them before the caller reuses its arrays).

    Raises
    ------
    ValueError
        A bad chunk, one line naming the trace.
    """
    clean = clean_chunk(spec.keys, spec.h, method, traces, with_links)
    if clean is None:
        return None
    keep = spec.selection.keys()
    kept = {k: v for k, v in clean.items() if k in keep}
    steps = clean[spec.keys[0]].shape[0]
    first = k0 + (-k0) % spec.stride                         # first recorded step
    ks = np.arange(first, k0 + steps, spec.stride, dtype=np.int64)
    rows = {k: v[first - k0::spec.stride] for k, v in kept.items()}
    leader = None
    if spec.leader_output is not None:
        lead = leader_position(clean["z"], spec.leader_output)
        leader = [lead.min(axis=0), lead.max(axis=0)]
    return RecordedChunk(method, int(k0), steps, {k: v.shape[1] for k, v in clean.items()},
                         ks, rows, {k: column_extremes(v) for k, v in kept.items()}, leader,
                         kept if spec.sample else None)


def spec_of(keys: Sequence[str], h: float, stride: int, selection: Selection,
            leader_output: np.ndarray | None) -> ChunkSpec:
    """A :class:`ChunkSpec` (its arrays copied and read-only)."""
    lead = None
    if leader_output is not None:
        lead = np.array(leader_output, dtype=np.float64)
        lead.flags.writeable = False
    return ChunkSpec(tuple(keys), float(h), int(stride), selection, lead)


def shapes(chunk: RecordedChunk) -> dict[str, np.ndarray]:
    """Empty (0, dim) stand-ins of the chunk's traces, for the checks of their columns."""
    return {k: np.empty((0, d)) for k, d in chunk.dims.items()}
