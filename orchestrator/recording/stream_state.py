"""What an :class:`~orchestrator.recording.stream.RrdStream` keeps between its sends
(each entity's static style logged once, each method's state) and the segments of a
checkpointed stream joined into one file."""
from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from .actuators import DEFAULT_DELTA_MAX, DEFAULT_N_MAX, send_limits
from .blueprint import LEGEND_ENTITY, _blueprint, _fleet_blueprint
from .network import LINKS_LEGEND_ENTITY, links_legend
from .scene import WorldStream, time_columns
from .summary import RunSummary
from .writer import _fleet_legend, _paper_legend

__all__ = ["add_footer", "closing_rows", "join_segments"]


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


def add_footer(path: Path) -> None:
    """Give a .rrd written without a footer its footer (``rerun rrd merge`` of the file
    alone: the same data, its small chunks compacted, the manifest that lets a reader
    enumerate its stores without a scan). If that fails the file stays as written (a
    footer-less .rrd opens in the viewer, read whole) and one line on stderr says so."""
    joined = path.with_name(path.name + ".joined")
    cmd = [sys.executable, "-m", "rerun", "rrd", "merge", "-o", str(joined), str(path)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0 or not joined.is_file():
        joined.unlink(missing_ok=True)
        lines = done.stderr.strip().splitlines()
        print(f"the recording keeps no footer (compacting it failed: "
              f"{lines[-1] if lines else done.returncode}); it opens in the viewer as it is",
              file=sys.stderr)
        return
    os.replace(joined, path)


def closing_rows(self: Any, sent: list[str], last: int) -> None:
    """What an :class:`~.stream.RrdStream` writes at its close: the legends, the actuator
    limits, the default blueprint (of the recorded groups; a live viewer's too)."""
    rec = self.rec
    compact = {m: self._runs[m].summary.compact() for m in sent}
    if self._fleet is None:
        rec.log(LEGEND_ENTITY, rr.TextDocument(_paper_legend(sent, self.colors),
                                               media_type=rr.MediaType.MARKDOWN), static=True)
        blueprint = _blueprint(compact, selection=self.selection)
    else:
        actuators = any("rpm" in compact[m] for m in sent)
        rec.log(LEGEND_ENTITY, rr.TextDocument(_fleet_legend(sent, self._fleet, actuators),
                                               media_type=rr.MediaType.MARKDOWN), static=True)
        with_links = [m for m in sent if m in self.links and self.selection.has("links")]
        if with_links:
            rec.log(LINKS_LEGEND_ENTITY, rr.TextDocument(
                links_legend(with_links), media_type=rr.MediaType.MARKDOWN), static=True)
        if actuators:
            ends = np.array([0, last // self.stride * self.stride], dtype=np.int64)
            send_limits(rec, time_columns(ends, self.h_ns),
                        self._fleet.n_max or DEFAULT_N_MAX,
                        self._fleet.delta_max or DEFAULT_DELTA_MAX)
        points = np.concatenate([np.vstack([
            compact[m]["x"][:, self._fleet.position_index].reshape(-1, 3),
            *self._runs[m].summary.leader]) for m in sent]) \
            if self.selection.has("scene") else np.zeros((1, 3))
        blueprint = _fleet_blueprint(sent, self._fleet, self.trail_ns, self.trail_steps,
                                     compact, links={m: self.links[m] for m in with_links}
                                     or None, points=points, selection=self.selection)
    self._rec.send_blueprint(blueprint, make_active=False, make_default=True)
    if self._viewer is not None:                # a live viewer: made its active one
        self._viewer.finish(blueprint)
