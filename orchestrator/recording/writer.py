"""Write the traces of one or more runs to a Rerun .rrd file: :func:`write_rrd` (through
:class:`~orchestrator.recording.stream.RrdStream`) and the ``send_columns`` writers of the
series of the paper layout and of the per-vehicle series of a fleet (its 3D scene:
:mod:`.scene`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr

from .actuators import send_actuators
from .layout import (
    _POSITION_NAMES,
    _SERIES,
    FLEET_TRACE_KEYS,
    TRACE_KEYS,
    TRUE_COLOR,
    FleetLayout,
    _Fleet,
    _lighter,
    _vehicle_colors,
    axis_colors,
    color_name,
    fleet_method_line,
    method_styles,
)
from .network import LINK_KEYS
from .scene import leader_position
from .validation import _validate, _validate_fleet

__all__ = ["write_rrd"]

#: how the viewer draws the samples that share a pixel column when zoomed out: the minimum
#: and the maximum (its default, the average, draws noise 2-4 times smaller than it is)
_AGGREGATION = "MinMax"
#: the width of the lines every method shares (the true disturbance and reference); each
#: method's own lines: :func:`~.layout.method_styles` (the ideal one wide, the Kalman
#: filter's thin and translucent over it)
_LINE_WIDTH = 1.0


def _send_block(rec: rr.RecordingStream, entity: str, values: np.ndarray, names: list[str],
                colors: list[tuple[int, int, int]], indexes: list[rr.TimeColumn],
                line: tuple[float, int] = (_LINE_WIDTH, 255)) -> int:
    """One multi-component series entity: static SeriesLines (one name/colour per column of
    ``values``, every line ``line`` = (width, alpha)) and one ``send_columns`` whose rows
    hold all k components.  Returns k."""
    width, alpha = line
    rec.log(entity, rr.SeriesLines(colors=[(*c[:3], alpha) for c in colors], names=names,
                                   widths=[width] * len(names),
                                   aggregation_policy=_AGGREGATION), static=True)
    rec.send_columns(entity, indexes=indexes,
                     columns=rr.Scalars.columns(
                         scalars=np.ascontiguousarray(values, dtype=np.float64)))
    return values.shape[1]


def _send_fleet_series(rec: rr.RecordingStream, method: str, traces: dict[str, np.ndarray],
                       fleet: _Fleet, method_index: int, stride: int,
                       indexes: list[rr.TimeColumn], n_methods: int = 1) -> int:
    """Per-vehicle multi-component series and the leader series of one run (recorded steps
    only); returns the number of scalar lines (components) written."""
    rec_traces = {key: traces[key][::stride] for key in ("e", "u", "x", "xhat", "w", "what", "z")}

    def shades(count: int, estimate: bool = False) -> list[tuple[int, int, int]]:
        colors = axis_colors(count, method_index)
        return [_lighter(c) for c in colors] if estimate else colors

    groups: list[tuple[str, str, np.ndarray, tuple[str, ...], str, bool]] = [
        ("e", "error/{m}", fleet.error_index, fleet.error_names, "", False),
        ("u", "control/{m}", fleet.control_index, fleet.control_names, "", False),
        ("x", "state/{m}/true", fleet.state_index, fleet.state_names, "", False),
        ("xhat", "state/{m}/estimate", fleet.state_index, fleet.state_names, " estimate", True),
    ]
    if fleet.disturbance_index is not None:
        groups += [
            ("w", "current/{m}/true", fleet.disturbance_index, fleet.disturbance_names, "", False),
            ("what", "current/{m}/estimate", fleet.disturbance_index, fleet.disturbance_names,
             " estimate", True),
        ]
    signals = 0
    line = fleet_method_line(method_index, n_methods)
    for key, template, index, names, suffix, is_estimate in groups:
        arr = rec_traces[key]
        line_names = [f"{method} {name}{suffix}" for name in names]
        colors = shades(len(names), is_estimate)
        for i in range(1, fleet.n + 1):
            signals += _send_block(rec, f"vehicles/{i}/{template.format(m=method)}",
                                   arr[:, index[i - 1]], line_names, colors, indexes, line)
    if "rpm" in traces:                  # the nonlinear vehicle: its actuators
        signals += send_actuators(rec, method, traces, fleet.n, stride, indexes, method_index,
                                  _vehicle_colors(fleet.n))
    if "setpoint" in traces:             # flown through the guidance FMUs: its set-points
        sp = traces["setpoint"][::stride]
        for i in range(1, fleet.n + 1):
            signals += _send_block(rec, f"vehicles/{i}/setpoint/{method}",
                                   sp[:, 3 * (i - 1):3 * i],
                                   [f"{method} speed (m/s)", f"{method} course (rad)",
                                    f"{method} depth (m)"], shades(3), indexes)
    leader = leader_position(rec_traces["z"], fleet.leader_output)  # (rows, 3)
    signals += _send_block(rec, f"leader/{method}", leader,
                           [f"{method} leader {c}" for c in _POSITION_NAMES], shades(3), indexes)
    return signals


#: true signals every method shares (same noise, no feedback): drawn once, in white; the
#: state x depends on each method's control and keeps the method's colour
_SHARED_TRUTH = ("w", "z")


def _paper_legend(methods: list[str], colors: dict[str, tuple[int, int, int]]) -> str:
    """The one-line colour legend of the paper layout (markdown)."""
    styles = method_styles(methods)

    def how(m: str) -> str:
        s = styles[m]
        if s.wide:
            return f"{color_name(colors[m])}, wide (under the thin lines)"
        return color_name(colors[m]) + (", thin, see-through" if s.viewer_alpha < 255 else "")
    names = " · ".join(f"**{m}** {how(m)}" for m in methods)
    return (f"{names} · true state: the method's colour, its estimate a lighter shade · "
            "disturbance and reference (the same for every method): white, drawn once · "
            "whole run shown; scroll or drag in a plot to zoom, double-click to reset")


def _fleet_legend(methods: list[str], fleet: _Fleet, actuators: bool = False) -> str:
    """The one-line colour legend of the fleet layout (markdown)."""
    comps = ", ".join(f"{n} {color_name(c)}" for n, c in zip(
        fleet.error_names, axis_colors(len(fleet.error_names), 0)))
    shades = " · ".join(f"**{m}**: {('full colour', 'darker', 'lighter')[i % 3]}"
                        + (", wide, see-through" if fleet_method_line(i, len(methods))[0]
                           > _LINE_WIDTH else "") for i, m in enumerate(methods))
    return (f"components: {comps} · {shades} · 3D: one colour per vehicle (numbered), "
            "leader gold with its whole path, formation targets as small pale points, "
            "communication edges grey, pinned links gold" + (
                " · actuators: one colour per vehicle (as in 3D), limits white" if actuators
                else ""))


#: optional fleet traces of the nonlinear vehicle (orchestrator.cosim.per_vehicle) and of
#: its guidance FMU (setpoint: per vehicle speed, course, depth)
_ACTUATOR_KEYS = ("attitude", "rpm", "rudder", "stern", "saturated", "setpoint")


def write_rrd(path: str | Path, runs: dict[str, dict[str, np.ndarray]], h: float, *,
              recording_name: str, application_id: str = "auv-cosim",
              fleet: FleetLayout | None = None, trail_seconds: float = 60.0,
              trail_sample_seconds: float = 0.5, stride: int = 1,
              scene_stride: int | None = None,
              links: dict[str, list[str]] | None = None) -> dict[str, float]:
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

    Returns
    -------
    dict[str, float]
        ``rrd_s`` (wall-clock seconds spent writing, validation excluded), ``signals``
        (number of scalar series written, an int: one per entity in the paper layout, one
        per component, i.e. per line, of each multi-component entity in the fleet layout)
        and ``bytes`` (file size in bytes, an int).

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
    from .stream import RrdStream  # it imports this module's series writers

    with RrdStream(path, list(clean), h, recording_name=recording_name, fleet=fleet,
                   stride=stride, scene_stride=scene_stride, trail_seconds=trail_seconds,
                   trail_sample_seconds=trail_sample_seconds, links=links,
                   application_id=application_id) as stream:
        for method, traces in clean.items():
            stream.send(method, 0, traces)
        return stream.close()


def _send_paper(rec: rr.RecordingStream, method: str, traces: dict[str, np.ndarray],
                colors: dict[str, tuple[int, int, int]], stride: int,
                indexes: list[rr.TimeColumn]) -> int:
    """One run's series of the paper layout, one entity per component (recorded steps
    only: every ``stride``-th row of ``traces``), each method in its style
    (:func:`~.layout.method_styles` of the methods of ``colors``); returns the number of
    entities."""
    signals = 0
    base = colors[method]
    light = _lighter(base)
    style_of = method_styles(list(colors))[method]
    width, alpha = style_of.width, style_of.viewer_alpha
    for key, template, suffix, is_estimate in _SERIES:
        arr = traces[key]
        if key in _SHARED_TRUTH:        # exogenous: the same for every method
            style = rr.SeriesLines(colors=[TRUE_COLOR], names=["true"],
                                   widths=[_LINE_WIDTH],
                                   aggregation_policy=_AGGREGATION)
        else:
            style = rr.SeriesLines(
                colors=[(*(light if is_estimate else base), alpha)],
                names=[f"{method}{suffix}"], widths=[width],
                aggregation_policy=_AGGREGATION)
        for i in range(1, arr.shape[1] + 1):
            entity = template.format(i=i, m=method)
            rec.log(entity, style, static=True)
            rec.send_columns(
                entity,
                indexes=indexes,
                columns=rr.Scalars.columns(
                    scalars=np.ascontiguousarray(arr[::stride, i - 1])),
            )
            signals += 1
    return signals
