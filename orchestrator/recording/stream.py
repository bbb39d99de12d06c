"""Write a .rrd chunk by chunk as a run goes, in bounded memory: :class:`RrdStream`.

A stream is opened on the run's methods; the master sends each method's traces in chunks of
steps (every simulated step, the layout :func:`~orchestrator.recording.whole.write_rrd`
takes), the methods one after the other, and closes it. The recorded rows are written to the
file as they come (gathered into blocks of ``chunk_rows``), to a temporary name in the same
folder (``.{name}.{pid}.part``) that :meth:`close` renames to the final one
(``os.replace``): the final name never holds a half-written file, and an earlier run's
file there stays until the rename. :meth:`abort` (or an exception in a
``with`` block) removes the temporary file.

What is recorded does not depend on the chunks: samples are chosen by global step (k % stride
== 0 for the series and the 3D scene; edges, trails and the leader's path as
:mod:`.scene` says), so the same traces sent in one chunk or in many give the same file
contents. What needs the whole run (the blueprint's y ranges and camera, the legends, the
actuator limits, the leader's whole path) is kept as it goes, bounded
(:mod:`.summary`), and written at :meth:`close`; a live viewer (``live``,
:mod:`.live`) gets a layout of its own first. A checkpoint (:meth:`checkpoint`) finishes
the file so far as a segment; :meth:`close` joins the segments. Memory: one chunk, the
rows gathered until written (at most :data:`PENDING_BYTES`), a few rows per trace column
and the file's footer, which grows about 850 bytes per Rerun chunk written
(docs/recording.md, "Written as the run goes").
"""
from __future__ import annotations

import os
import pickle
import sys
import time
import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from .chunks import RecordedChunk, digest, shapes, spec_of
from .layout import FLEET_TRACE_KEYS, TRACE_KEYS, FleetLayout, _Fleet, method_color
from .live import start_live
from .network import send_links
from .scene import WorldStream, time_columns
from .selection import Selection
from .stream_state import _Run, _StaticOnce, add_footer, closing_rows, join_segments
from .summary import SAMPLE_ROWS
from .validation import (
    _method_name,
    _positive_int,
    _positive_ns,
    _step_ns,
    _validate_fleet,
)
from .writer import (
    _send_fleet_series,
    _send_paper,
)

__all__ = ["CHUNK_ROWS", "PENDING_BYTES", "SAMPLE_ROWS", "RrdStream"]

#: recorded rows gathered before they are written (one Rerun chunk per entity), by default
CHUNK_ROWS = 4096
#: ... or fewer, once they hold this many bytes (a wide fleet's rows)
PENDING_BYTES = 32 << 20


class RrdStream:
    """A .rrd written chunk by chunk (module docstring).

    Parameters
    ----------
    path : str or Path
        The final .rrd file (replaced by :meth:`close`).
    methods : Sequence[str]
        The methods that may be sent, in their legend and colour order.
    h : float
        Step, s (> 0); times are stored as round(h * 1e9) integer nanoseconds.
    recording_name, application_id, fleet, stride, scene_stride, trail_seconds, \
trail_sample_seconds, links
        As :func:`~orchestrator.recording.whole.write_rrd`.
    chunk_rows : int, optional
        Recorded rows gathered before they are written (one Rerun chunk per entity; fewer
        when they reach :data:`PENDING_BYTES`); 1 writes every send at once (a live viewer).
    footer : bool, optional
        Write the file's footer (Rerun's chunk manifest, kept in memory until the close). A
        live stream writes none as it goes (its many small writes would grow the manifest
        without bound) and gets it at the close, its chunks compacted
        (:func:`.stream_state.add_footer`).
    live : str or None, optional
        A Rerun viewer's URL (``rerun+http://HOST:PORT/proxy``): every row written to the
        file goes to it too, after a live layout of its own, and the final blueprint at
        the close (:mod:`.live`); the file is the same. Check it first
        (:func:`.live.check_viewer`): Rerun's sink does not wait for the viewer.
    record : Sequence[str] or None, optional
        The groups of outputs recorded (:mod:`.selection`; None: all): the file holds
        their entities and the blueprint their views only.

    Raises
    ------
    ValueError
        A bad argument (as :func:`~orchestrator.recording.whole.write_rrd`); nothing is
        written then.
    RuntimeError
        If Rerun logging is disabled (``RERUN=off``).
    """

    def __init__(self, path: str | Path, methods: Sequence[str], h: float, *,
                 recording_name: str, fleet: FleetLayout | None = None, stride: int = 1,
                 scene_stride: int | None = None, trail_seconds: float = 60.0,
                 trail_sample_seconds: float = 0.5,
                 links: Mapping[str, Sequence[str]] | None = None,
                 application_id: str = "auv-cosim", chunk_rows: int = CHUNK_ROWS,
                 footer: bool = True, live: str | None = None,
                 record: Sequence[str] | None = None) -> None:
        t0 = time.perf_counter()
        self.chunk_rows = _positive_int(chunk_rows, "chunk_rows")
        self.methods = [_method_name(m) for m in methods]
        if not self.methods or len(set(self.methods)) != len(self.methods):
            raise ValueError(f"write_rrd: methods must be distinct names, at least one, got "
                             f"{list(methods)!r}")
        self.h_ns = _step_ns(h)
        self.h = float(h)
        self.stride = _positive_int(stride, "stride")
        if scene_stride is not None:
            scene_stride = _positive_int(scene_stride, "scene_stride")
            if scene_stride % self.stride:
                raise ValueError(f"write_rrd: scene_stride = {scene_stride} must be a multiple "
                                 f"of stride = {self.stride}")
        self.fleet_layout = fleet
        self.keys = FLEET_TRACE_KEYS if fleet is not None else TRACE_KEYS
        self.selection = Selection.of(fleet is not None, record)
        self.spec = spec_of(self.keys, h, self.stride, self.selection,
                            None if fleet is None else fleet.leader_output)
        if fleet is not None:
            self.trail_ns, sample_ns = (_positive_ns(v, name) for v, name in (
                (trail_seconds, "trail_seconds"),
                (trail_sample_seconds, "trail_sample_seconds")))
            # ceil: the step range covers at least trail_seconds
            self.trail_steps = -(-self.trail_ns // self.h_ns)
            self.trail_stride = self.stride * max(1, round(sample_ns / (self.stride * self.h_ns)))
            self.scene_stride = self.trail_stride if scene_stride is None else scene_stride
        self.links = {m: list(v) for m, v in links.items()} if links else {}
        self.colors = method_color(self.methods)
        self.path = Path(path)
        self.tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.part")
        self._fleet: _Fleet | None = None
        self._runs: dict[str, _Run] = {}
        self._current: str | None = None
        self.signals = 0
        self._open = False
        self.application_id, self.recording_id = application_id, str(uuid.uuid4())
        self.recording_name = recording_name
        #: written as it goes / added at the close (a live stream: :func:`add_footer`)
        self.footer, self.footer_at_close = bool(footer) and live is None, bool(footer) and \
            live is not None
        self.live = live
        self._viewer: Any = None                # a live viewer's own stream (.live)
        #: the files of the run before its checkpoints (:meth:`checkpoint`), in order, in
        #: :attr:`segment_dir`
        self.segments: list[str] = []
        self.segment_dir: Path | None = None
        self.rec = _StaticOnce(None)            # type: ignore[arg-type]
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._connect()
        self.seconds = time.perf_counter() - t0

    def _connect(self) -> None:
        """A recording (the stream's ids) writing to the temporary file."""
        rec = rr.RecordingStream(self.application_id, recording_id=self.recording_id)
        if not rec.is_enabled():
            raise RuntimeError("write_rrd: Rerun logging is disabled (RERUN env var?); refusing "
                               "to write an empty .rrd")
        self._rec = rec
        self.rec.rec = rec
        self._open = True
        try:
            self._sinks(rec)
            rec.send_recording_name(self.recording_name)
            if self.fleet_layout is not None and self.selection.has("scene"):
                rec.log("world", rr.ViewCoordinates.FRD, static=True)
        except BaseException:
            self.abort()
            raise

    # -- checkpoints ----------------------------------------------------------------------

    def checkpoint(self, folder: str | Path) -> bytes:
        """Finish the file so far as a segment in ``folder`` (a complete .rrd of its own,
        ``segment-NNNN.rrd``), go on in a new temporary file, and return the stream's state
        for :meth:`resumed` (a run resumed from the checkpoint goes on from here; the
        segments and the rest are joined into one file at :meth:`close`)."""
        if not self._open:
            raise RuntimeError(f"RrdStream {self.path}: checkpoint after close or abort")
        t0 = time.perf_counter()
        if self._current is not None:
            self._flush(self._current, self._runs[self._current])
        self._flush_sinks()
        self._rec.disconnect()
        del self._rec
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        name = f"segment-{len(self.segments):04d}.rrd"
        os.replace(self.tmp, folder / name)
        self.segments.append(name)
        self.segment_dir = folder
        state = pickle.dumps(self, protocol=pickle.HIGHEST_PROTOCOL)
        self._connect()
        self.seconds += time.perf_counter() - t0
        return state

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state.pop("_rec", None)
        state["_viewer"] = state["live"] = None      # a resumed run: live if asked again
        return state

    @classmethod
    def resumed(cls, state: bytes, folder: str | Path, path: str | Path,
                live: str | None = None) -> RrdStream:
        """The stream of a checkpoint (:meth:`checkpoint`'s state) going on: its segments
        are in ``folder``, its final file is ``path``; ``live``: a viewer's URL that gets
        the live layout, the recording so far (the segments) and then the rows to come."""
        self = pickle.loads(state)
        self.segment_dir, self.path = Path(folder), Path(path)
        missing = [s for s in self.segments if not (self.segment_dir / s).is_file()]
        if missing:
            raise ValueError(f"resuming {self.path}: the recording's segment(s) "
                             f"{', '.join(missing)} are not in {self.segment_dir}")
        self.tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.part")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if live is not None:            # the file gets its footer at the join; rows at once
            self.live, self.footer, self.chunk_rows = live, False, 1
        self._connect()
        if live is not None and self._current is not None:
            run = self._runs[self._current]
            self._viewer = start_live(self, self._current,
                                      {k: np.empty((0, d)) for k, d in run.dims.items()})
            self._viewer.replay([self.segment_dir / n for n in self.segments])
        return self

    def _sinks(self, rec: rr.RecordingStream) -> None:
        """Where the recording goes: the temporary file and, with ``live`` (a viewer's
        URL), that viewer too (Rerun's file and gRPC sinks: the same rows, as they are
        written)."""
        if self.live is None:
            rec.save(self.tmp, write_footer=self.footer)
        else:
            rec.set_sinks(rr.FileSink(self.tmp, write_footer=self.footer),
                          rr.GrpcSink(self.live))

    def _flush_sinks(self) -> None:
        """Flush what was logged to the sinks; a live viewer that went away (closed, its
        connection severed) is said once on stderr and the file goes on."""
        try:
            self._rec.flush()
        except RuntimeError as exc:
            if self.live is None or "grpc" not in str(exc).lower():
                raise
            if not getattr(self, "_viewer_gone", False):
                self._viewer_gone = True
                print(f"live viewer at {self.live} gone ({str(exc).splitlines()[0]}); the run "
                      f"goes on, writing {self.path}", file=sys.stderr, flush=True)

    # -- sending --------------------------------------------------------------------------

    def digest(self, method: str, k0: int, traces: Mapping[str, Any],
               links: Sequence[str] | None = None) -> RecordedChunk | None:
        """The chunk reduced to what the file keeps (:func:`.chunks.digest`), checked."""
        return digest(self.spec, method, k0, traces,
                      links is not None or method in self.links)

    def send(self, method: str, k0: int, traces: Mapping[str, Any],
             links: Sequence[str] | None = None) -> None:
        """Record rows k0 .. k0 + n - 1 (every simulated step) of one method's traces: its
        recorded steps are written once ``chunk_rows`` of them are gathered (or the method
        ends: the next method's first send, or :meth:`close`).

        Parameters
        ----------
        method : str
            One of the stream's methods. All chunks of a method come before those of the
            next; a method whose chunks ended (another was sent since) cannot be sent again.
        k0 : int
            Global step of the first row; the method's first chunk may start anywhere
            (>= 0), each later one where the previous ended.
        traces : Mapping[str, array]
            Trace key -> array (n, dim), the keys and shapes of
            :func:`~orchestrator.recording.whole.write_rrd` (the actuator traces and, for a
            method over links, the link traces too); the same dims in every chunk.
            A chunk of no rows is ignored.
        links : Sequence[str] or None, optional
            The method's link names ("j -> i", one per column of its ``link_*`` traces) if
            they were not given when the stream was opened: with its first chunk only.

        Raises
        ------
        ValueError
            A bad chunk (the stream stays usable), an unknown or finished method, or a gap.
        RuntimeError
            If the stream is closed or aborted.
        """
        t0 = time.perf_counter()
        self._check_send(method, k0, links)
        chunk = self.digest(method, int(k0), traces, links)
        self.seconds += time.perf_counter() - t0
        if chunk is not None:
            self.take(chunk, links)

    def _check_send(self, method: str, k0: int, links: Sequence[str] | None) -> None:
        if not self._open:
            raise RuntimeError(f"RrdStream {self.path}: send after close or abort")
        if method not in self.colors:
            raise ValueError(f"write_rrd: method {method!r} is not one of the stream's "
                             f"{self.methods}")
        if isinstance(k0, (bool, np.bool_)) or not isinstance(k0, (int, np.integer)) or k0 < 0:
            raise ValueError(f"write_rrd: k0 must be a step number >= 0, got {k0!r}")
        k0 = int(k0)
        run = self._runs.get(method)
        if run is not None and method != self._current:
            raise ValueError(f"write_rrd: method {method!r} was finished (its chunks must "
                             f"come before the next method's)")
        if run is not None and k0 != run.next_k:
            raise ValueError(f"write_rrd: method {method!r} chunk starts at step {k0}, the "
                             f"previous one ended at {run.next_k - 1}")
        if links is not None:
            links = list(links)
            if self.links.get(method, links) != links or (run is not None
                                                           and method not in self.links):
                raise ValueError(f"write_rrd: method {method!r}: links {links} differ from "
                                 "those given before (at the open or with its first chunk)")

    def take(self, chunk: RecordedChunk, links: Sequence[str] | None = None) -> None:
        """Record a chunk's digest (:meth:`digest`; :meth:`send` is both): what a stream
        in the writer child gets (:class:`~.background.ChildStream`)."""
        t0 = time.perf_counter()
        method, k0 = chunk.method, chunk.k0
        self._check_send(method, k0, links)
        run = self._runs.get(method)
        if links is not None:
            self.links[method] = list(links)
        dims = chunk.dims
        if run is None:
            fleet = None
            if self.fleet_layout is not None:
                fleet = _validate_fleet(self.fleet_layout, {method: shapes(chunk)})
            self._finish_current()
            run = _Run(self.methods.index(method), k0, dims, sample=fleet is None)
            if fleet is not None:
                self._fleet = self._fleet or fleet
            if fleet is not None and self.selection.has("scene"):
                run.world = WorldStream(self.rec, method, self._fleet, self.h_ns, self.stride,
                                        self.scene_stride, self.trail_stride)
            if self.live is not None and not self._runs:   # the viewer's layout first
                self._viewer = start_live(self, method, {**shapes(chunk), **chunk.rows})
            self._runs[method] = run
            self._current = method
        elif dims != run.dims:
            raise ValueError(f"write_rrd: method {method!r} chunk has trace columns {dims}, "
                             f"its first chunk had {run.dims}")
        try:
            self._write(method, run, chunk)
        except BaseException:
            self.abort()
            raise
        self.seconds += time.perf_counter() - t0

    def _write(self, method: str, run: _Run, chunk: RecordedChunk) -> None:
        run.summary.add(chunk)
        ks, rows = chunk.ks, chunk.rows
        run.next_k = chunk.k0 + chunk.steps
        if not ks.size:
            return
        size = sum(v.nbytes for v in rows.values())
        run.last_recorded = int(ks[-1])
        if run.pending_rows + ks.size >= self.chunk_rows or \
                run.pending_bytes + size >= PENDING_BYTES:
            run.pending.append((ks, rows))                     # written now: no copy
            self._flush(method, run)
        else:                                                  # the caller may reuse its arrays
            run.pending.append((ks, {k: v.copy() for k, v in rows.items()}))
            run.pending_rows += ks.size
            run.pending_bytes += size

    def _flush(self, method: str, run: _Run) -> None:
        """Write the method's pending recorded rows (one Rerun chunk per entity)."""
        if not run.pending:
            return
        if len(run.pending) == 1:
            ks, rows = run.pending[0]
        else:
            ks = np.concatenate([p[0] for p in run.pending])
            rows = {k: np.concatenate([p[1][k] for p in run.pending]) for k in run.pending[0][1]}
        run.pending, run.pending_rows, run.pending_bytes = [], 0, 0
        indexes = time_columns(ks, self.h_ns)
        if self._fleet is None:
            lines = _send_paper(self.rec, method, rows, self.colors, 1, indexes)
        else:
            lines = _send_fleet_series(self.rec, method, rows, self._fleet, run.index, 1,
                                       indexes, len(self.methods), self.selection)
            if method in self.links and self.selection.has("links"):
                lines += send_links(self.rec, method, rows, self.links[method], 1, indexes,
                                    run.index, n=self._fleet.n)
        if not run.counted:
            self.signals += lines
            run.counted = True
        if run.world is not None:
            run.world.send(ks, rows)
        self._flush_sinks()

    def _finish_current(self) -> None:
        """The current method's pending rows and the scene rows that wait for its end
        (:meth:`WorldStream.close`)."""
        run = self._runs.get(self._current) if self._current is not None else None
        if run is None:
            return
        self._flush(self._current, run)
        if run.world is not None:
            run.world.close()
            run.world = None

    # -- closing --------------------------------------------------------------------------

    def close(self, last_step: int | None = None) -> dict[str, float]:
        """Write what needs the whole run (blueprint, legends, limits, the scene's last rows)
        and rename the file to its final name.

        Parameters
        ----------
        last_step : int or None, optional
            The run's last step, if known (>= every step sent): the actuator limits are drawn
            up to the last recorded step at or before it. None: the last step sent.

        Returns
        -------
        dict[str, float]
            ``rrd_s`` (wall-clock seconds spent in the stream's calls), ``signals`` (scalar
            series written, counted as :func:`~orchestrator.recording.whole.write_rrd`
            does), ``bytes`` (the file's size) and ``recorded_groups``
            (:meth:`recorded_groups`).

        Raises
        ------
        ValueError
            If nothing was sent, or ``last_step`` is before a step sent; the temporary file
            is removed then.
        RuntimeError
            If the stream is closed or aborted.
        """
        if not self._open:
            raise RuntimeError(f"RrdStream {self.path}: close after close or abort")
        t0 = time.perf_counter()
        try:
            sent = [m for m in self.methods if m in self._runs
                    and self._runs[m].last_recorded >= 0]
            if not sent:
                raise ValueError("write_rrd: no recorded step was sent; nothing to write")
            last = max(r.next_k - 1 for r in self._runs.values())
            if last_step is not None:
                if int(last_step) < last:
                    raise ValueError(f"write_rrd: last_step = {last_step} is before step "
                                     f"{last}, which was sent")
                last = int(last_step)
            self._finish_current()
            closing_rows(self, sent, last)
            self._flush_sinks()
        except BaseException:
            self.abort()
            raise
        # Dropping the file sink finishes the file (footer + manifest) before returning.
        self._rec.disconnect()
        del self._rec, self.rec
        self._open = False
        if self.segments:               # a checkpointed run: join its files (nothing lost)
            join_segments([Path(self.segment_dir) / n for n in self.segments], self.tmp)
        elif self.footer_at_close:
            add_footer(self.tmp)
        os.replace(self.tmp, self.path)
        self.seconds += time.perf_counter() - t0
        return {"rrd_s": self.seconds, "signals": self.signals,
                "bytes": self.path.stat().st_size, "recorded_groups": self.recorded_groups()}

    def recorded_groups(self) -> list[str]:
        """The groups of the selection the file holds: those whose traces some method sent
        (links, actuators and set-points only where a run had them)."""
        sent = {k for run in self._runs.values() for k in run.dims}
        return [g for g in self.selection.names()
                if sent & set(self.selection.table[g][0])]

    def abort(self) -> None:
        """Stop writing and remove the temporary file (the final name is left as it was).
        Does nothing after :meth:`close` or a first abort."""
        if not self._open:
            return
        self._open = False
        try:
            self._rec.disconnect()
        finally:
            del self._rec, self.rec
            self.tmp.unlink(missing_ok=True)

    def __enter__(self) -> RrdStream:
        return self

    def __exit__(self, *exc: object) -> None:
        """Aborts a stream that was not closed (an exception, or no :meth:`close`)."""
        self.abort()
