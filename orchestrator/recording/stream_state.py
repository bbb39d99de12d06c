"""What an :class:`~orchestrator.recording.stream.RrdStream` keeps between its sends
(each entity's static style logged once, each method's state) and the segments of a
checkpointed stream joined into one file."""
from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from .network import LINK_KEYS
from .scene import WorldStream
from .summary import RunSummary
from .validation import _validate
from .writer import _ACTUATOR_KEYS

__all__ = ["clean_chunk", "join_segments"]


class _StaticOnce:
    """The recording, logging each entity's static style only the first time (the series
    writers log it with every chunk)."""

    def __init__(self, rec: rr.RecordingStream) -> None:
        self.rec = rec
        self._seen: set[tuple[str, type]] = set()

    def log(self, entity: str, data: Any, *args: Any, static: bool = False,
            **kwargs: Any) -> None:
        if static:
            key = (entity, type(data))
            if key in self._seen:
                return
            self._seen.add(key)
        self.rec.log(entity, data, *args, static=static, **kwargs)

    def send_columns(self, *args: Any, **kwargs: Any) -> None:
        self.rec.send_columns(*args, **kwargs)

    def __getstate__(self) -> dict[str, Any]:
        """What a checkpoint keeps: the statics logged (not the recording's connection)."""
        return {"rec": None, "_seen": set(self._seen)}


class _Run:
    """One method's state in the stream."""

    def __init__(self, index: int, k0: int, dims: dict[str, int], sample: bool) -> None:
        self.index, self.next_k, self.dims = index, k0, dims
        self.summary = RunSummary(sample)
        self.world: WorldStream | None = None
        self.counted = False
        self.last_recorded = -1
        self.pending: list[tuple[np.ndarray, dict[str, np.ndarray]]] = []   # recorded rows
        self.pending_rows = 0
        self.pending_bytes = 0


def join_segments(segments: Sequence[Path], tmp: Path) -> None:
    """The segment files and then ``tmp`` joined into one .rrd at ``tmp`` (``rerun rrd
    merge``: Rerun's own join, which checks every chunk; ``rerun rrd route``, which would
    not decode them, fails on files with a footer in Rerun 0.41).

    Raises
    ------
    RuntimeError
        If the join fails, with Rerun's last line; nothing is lost: ``tmp`` becomes the
        next segment file beside the others, and the message names them.
    """
    joined = tmp.with_name(tmp.name + ".joined")
    cmd = [sys.executable, "-m", "rerun", "rrd", "merge", "-o", str(joined),
           *(str(s) for s in segments), str(tmp)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0 or not joined.is_file():
        joined.unlink(missing_ok=True)
        folder = Path(segments[-1]).parent
        os.replace(tmp, folder / f"segment-{len(segments):04d}.rrd")
        lines = done.stderr.strip().splitlines()
        raise RuntimeError(f"joining the recording's {len(segments) + 1} segments failed: "
                           f"{lines[-1] if lines else done.returncode}; the recording is "
                           f"kept in {len(segments) + 1} files, {folder}/segment-*.rrd (the "
                           "viewer opens them together)")
    os.replace(joined, tmp)


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
