"""The ``send_columns`` writers of the series of the paper layout and of the per-vehicle
series of a fleet (its 3D scene: :mod:`.scene`), and the legends, that
:class:`~orchestrator.recording.stream.RrdStream` writes with (a whole run at once:
:func:`orchestrator.recording.whole.write_rrd`)."""
from __future__ import annotations

import numpy as np
import rerun as rr

from .actuators import send_actuators
from .layout import (
    _POSITION_NAMES,
    _SERIES,
    TRUE_COLOR,
    _Fleet,
    _lighter,
    _vehicle_colors,
    axis_colors,
    color_name,
    fleet_method_line,
    method_styles,
)
from .scene import leader_position
from .selection import Selection

__all__: list[str] = []           # used by the recording modules only

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
                       indexes: list[rr.TimeColumn], n_methods: int = 1,
                       selection: Selection | None = None) -> int:
    """Per-vehicle multi-component series and the leader series of one run (recorded steps
    only) of the groups ``selection`` records (default: all); returns the number of scalar
    lines (components) written."""
    selection = selection or Selection(fleet=True)
    rec_traces = {key: traces[key][::stride] for key in ("e", "u", "x", "xhat", "w", "what", "z")
                  if key in traces}

    def shades(count: int, estimate: bool = False) -> list[tuple[int, int, int]]:
        colors = axis_colors(count, method_index)
        return [_lighter(c) for c in colors] if estimate else colors

    groups: list[tuple[str, str, np.ndarray, tuple[str, ...], str, bool]] = []
    if selection.has("error"):
        groups.append(("e", "error/{m}", fleet.error_index, fleet.error_names, "", False))
    if selection.has("control"):
        groups.append(("u", "control/{m}", fleet.control_index, fleet.control_names, "", False))
    if selection.has("state"):
        groups += [("x", "state/{m}/true", fleet.state_index, fleet.state_names, "", False),
                   ("xhat", "state/{m}/estimate", fleet.state_index, fleet.state_names,
                    " estimate", True)]
    if fleet.disturbance_index is not None and selection.has("current"):
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
    if "rpm" in traces and selection.has("actuators"):   # the nonlinear vehicle's actuators
        signals += send_actuators(rec, method, traces, fleet.n, stride, indexes, method_index,
                                  _vehicle_colors(fleet.n))
    if "setpoint" in traces and selection.has("setpoint"):   # flown through guidance FMUs
        sp = traces["setpoint"][::stride]
        for i in range(1, fleet.n + 1):
            signals += _send_block(rec, f"vehicles/{i}/setpoint/{method}",
                                   sp[:, 3 * (i - 1):3 * i],
                                   [f"{method} speed (m/s)", f"{method} course (rad)",
                                    f"{method} depth (m)"], shades(3), indexes)
    if selection.has("leader"):
        leader = leader_position(rec_traces["z"], fleet.leader_output)  # (rows, 3)
        signals += _send_block(rec, f"leader/{method}", leader,
                               [f"{method} leader {c}" for c in _POSITION_NAMES], shades(3),
                               indexes)
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
        if key not in traces:           # not recorded (a selection of outputs)
            continue
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
