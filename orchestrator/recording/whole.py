"""A whole run's traces written to a .rrd at once: :func:`write_rrd`, one
:class:`~orchestrator.recording.stream.RrdStream` send per method and its close (the
streamed file and this one are the same file)."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .layout import FLEET_TRACE_KEYS, TRACE_KEYS, FleetLayout
from .network import LINK_KEYS
from .stream import RrdStream
from .validation import _validate, _validate_fleet
from .writer import _ACTUATOR_KEYS

__all__ = ["write_rrd"]


def write_rrd(path: str | Path, runs: dict[str, dict[str, np.ndarray]], h: float, *,
              recording_name: str, application_id: str = "auv-cosim",
              fleet: FleetLayout | None = None, trail_seconds: float = 60.0,
              trail_sample_seconds: float = 0.5, stride: int = 1,
              scene_stride: int | None = None,
              links: dict[str, list[str]] | None = None,
              record: Sequence[str] | None = None) -> dict[str, float]:
    """Write the traces of one or more runs to a Rerun .rrd file with a default blueprint.

    Parameters
    ----------
    path : str or Path
        Output .rrd file (overwritten).
    runs : dict[str, dict[str, np.ndarray]]
        Method name -> traces; each trace (keys :data:`TRACE_KEYS`) a float array of shape
        (steps, dim) in the simulation's own units (states, errors, references in the plant's
        units; controls in the actuator's units).  Row k is sample k, at time k*h seconds.
        All traces of all runs must have the same number of steps; dims may differ per key.
        Extra keys are ignored.
    h : float
        Sampling period in seconds (> 0); stored as round(h * 1e9) integer nanoseconds.
    recording_name : str
        Human-readable recording name shown by the viewer.
    application_id : str, optional
        Rerun application id (the default blueprint applies to this id).
    fleet : FleetLayout or None, optional
        If given, the traces are those of a fleet of N vehicles laid out as described by the
        :class:`FleetLayout`; the compact per-vehicle layout and a 3D scene per run are
        written *instead of* the per-component layout, and the default blueprint becomes the
        fleet layout (see docs/recording.md).  Checked against the traces of every run.
    trail_seconds : float, optional
        Length (s, > 0) of the vehicle trails in the 3D view: the trail entity is shown over
        the visible time range [cursor - trail_seconds, cursor].  Only used with ``fleet``.
    trail_sample_seconds : float, optional
        Spacing (s, > 0) of the trail samples: one trail segment per vehicle every
        stride * max(1, round(trail_sample_seconds / (stride * h))) steps (plus the last
        recorded step).  Only used with ``fleet``.
    stride : int, optional
        Record only every stride-th step (k = 0, stride, 2*stride, ...), a positive int.  The
        time columns keep the true step index and sim_time.  Default 1: every step.
    scene_stride : int or None, optional
        Steps between two samples of the 3D edges (``world/{m}/edges``), a positive multiple
        of ``stride``; default (None) the trail stride.  Only used with ``fleet``.
    links : dict[str, list[str]] or None, optional
        Per method over acoustic links the link of each column of its ``link_*`` traces
        ("j -> i"): each link's counts and each vehicle's age of information are recorded
        (:mod:`orchestrator.recording.network`).  Only used with ``fleet``.
    record : Sequence[str] or None, optional
        The groups of outputs written (:mod:`orchestrator.recording.selection`; None: all):
        the file holds their entities and the blueprint their views only.

    Returns
    -------
    dict[str, float]
        ``rrd_s`` (wall-clock seconds spent writing, validation excluded), ``signals``
        (number of scalar series written, an int: one per entity in the paper layout, one
        per component, i.e. per line, of each multi-component entity in the fleet layout)
        ``bytes`` (file size in bytes, an int) and ``recorded_groups`` (the groups of
        outputs the file holds, :mod:`orchestrator.recording.selection`).

    Raises
    ------
    ValueError
        If ``runs`` is empty, a run misses a trace key, a trace is not 2-D, step counts
        differ, a method name is not a valid entity path part, ``h`` is not positive or
        ``stride`` is not a positive integer; or if ``fleet`` does not fit the traces (an
        index out of range, a wrong shape, an edge or pinned vehicle that does not exist,
        ...), ``trail_seconds`` / ``trail_sample_seconds`` is not positive or
        ``scene_stride`` is not a positive multiple of ``stride``.  Nothing is written then.
    RuntimeError
        If Rerun logging is disabled (e.g. ``RERUN=off``), since the file would be empty.
    """
    clean, steps, h_ns = _validate(runs, h,
                                   FLEET_TRACE_KEYS if fleet is not None else TRACE_KEYS)
    for m in clean:                     # the nonlinear vehicle's attitude and actuators
        for key in _ACTUATOR_KEYS:
            if key in runs[m]:
                arr = np.asarray(runs[m][key], dtype=np.float64)
                if arr.ndim != 2 or arr.shape[0] != steps:
                    raise ValueError(f"write_rrd: run {m!r} trace {key!r} has shape "
                                     f"{arr.shape}, expected ({steps}, ...)")
                clean[m][key] = arr
    if fleet is not None:
        _validate_fleet(fleet, clean)
    links = {m: v for m, v in links.items() if m in clean} if links else None
    for m in links or ():
        clean[m].update({k: np.asarray(runs[m][k]) for k in LINK_KEYS})
    with RrdStream(path, list(clean), h, recording_name=recording_name, fleet=fleet,
                   stride=stride, scene_stride=scene_stride, trail_seconds=trail_seconds,
                   trail_sample_seconds=trail_sample_seconds, links=links,
                   application_id=application_id, record=record) as stream:
        for method, traces in clean.items():
            stream.send(method, 0, traces)
        return stream.close()
