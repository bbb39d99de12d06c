"""Write the traces of one or more runs to a Rerun .rrd file: :func:`write_rrd` and the
``send_columns`` writers of the per-vehicle series and the 3D scene of a fleet."""
from __future__ import annotations

import os
import time
import uuid
from pathlib import Path

import numpy as np
import rerun as rr

from plant_model.remus100.rigid_body import quaternion_xyzw

from .actuators import DEFAULT_DELTA_MAX, DEFAULT_N_MAX, send_actuators, send_limits
from .blueprint import LEGEND_ENTITY, _blueprint, _fleet_blueprint
from .layout import (
    _POSITION_NAMES,
    _SERIES,
    _SIM_TIME,
    _STEP,
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
    method_color,
    method_styles,
)
from .network import LINK_KEYS, LINKS_LEGEND_ENTITY, links_legend, send_links
from .validation import _positive_int, _positive_ns, _validate, _validate_fleet

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
    leader = rec_traces["z"] @ fleet.leader_output.T  # (rows, 3)
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


def _time_columns(k: np.ndarray, h_ns: int) -> list[rr.TimeColumn]:
    return [rr.TimeColumn(_STEP, sequence=k),
            rr.TimeColumn(_SIM_TIME, duration=(k * h_ns).astype("timedelta64[ns]"))]


def _sample_steps(steps: int, every: int, last: int) -> np.ndarray:
    """Steps 0, every, 2*every, ... (< steps), then ``last`` if it is not among them."""
    ks = np.arange(0, steps, every, dtype=np.int64)
    if ks[-1] != last:
        ks = np.append(ks, last)
    return ks


#: optional fleet traces of the nonlinear vehicle (orchestrator.cosim.per_vehicle) and of
#: its guidance FMU (setpoint: per vehicle speed, course, depth)
_ACTUATOR_KEYS = ("attitude", "rpm", "rudder", "stern", "saturated", "setpoint")

#: the hull drawn in the 3D view: the REMUS 100's 1.6 m x 0.19 m spheroid, 3 times enlarged
#: to be seen at formation scale (m, body axes x forward, y starboard, z down)
_HULL_HALF_SIZES = (2.4, 0.285, 0.285)


#: distance (m) of a vehicle's number from the vehicle, to starboard of its course
_LABEL_OFFSET = 4.0


def _label_positions(pos: np.ndarray) -> np.ndarray:
    """(rows, N, 3) positions of the vehicles' numbers: ``_LABEL_OFFSET`` m to starboard of
    each vehicle's horizontal course (east when it does not move), so the number sits off
    its own trail."""
    if pos.shape[0] < 2:
        vel = np.zeros_like(pos)
    else:
        vel = np.gradient(pos, axis=0)
    right = np.stack([-vel[..., 1], vel[..., 0], np.zeros(vel.shape[:-1])], axis=-1)
    norm = np.linalg.norm(right, axis=-1, keepdims=True)
    east = np.broadcast_to(np.array([0.0, 1.0, 0.0]), right.shape)
    unit = np.where(norm > 1e-9, right / np.maximum(norm, 1e-12), east)
    return pos + _LABEL_OFFSET * unit


def _send_fleet_world(rec: rr.RecordingStream, method: str, traces: dict[str, np.ndarray],
                      fleet: _Fleet, h_ns: int, stride: int, scene_stride: int,
                      trail_stride: int) -> None:
    """The 3D scene of one run under ``world/{method}``: one partition per sample, no per-step
    logs."""
    n, steps = fleet.n, traces["x"].shape[0]
    root = f"world/{method}"
    colors = _vehicle_colors(n)
    ks = np.arange(0, steps, stride, dtype=np.int64)                 # recorded steps
    rows = ks.size
    indexes = _time_columns(ks, h_ns)
    pos_all = traces["x"][:, fleet.position_index]                    # (steps, N, 3) float64
    lead_all = traces["z"] @ fleet.leader_output.T                    # (steps, 3)
    pos, leader = pos_all[ks], lead_all[ks]
    targets = leader[:, None, :] + fleet.offsets[None, :, :]          # (rows, N, 3)

    rec.log(root, rr.ViewCoordinates.FRD, static=True)
    rec.log(f"{root}/vehicles", rr.Points3D.from_fields(
        radii=[1.0], colors=colors, labels=[str(i) for i in range(1, n + 1)], show_labels=False),
        static=True)
    rec.send_columns(f"{root}/vehicles", indexes=indexes, columns=rr.Points3D.columns(
        positions=pos.reshape(rows * n, 3).astype(np.float32)).partition(np.full(rows, n)))
    # the numbers beside the vehicles, off their own trails and edges: to starboard
    rec.log(f"{root}/labels", rr.Points3D.from_fields(
        radii=[0.05], colors=[_lighter(tuple(int(v) for v in c), 0.45) for c in colors],
        labels=[str(i) for i in range(1, n + 1)], show_labels=True),
        static=True)
    rec.send_columns(f"{root}/labels", indexes=indexes, columns=rr.Points3D.columns(
        positions=_label_positions(pos).reshape(rows * n, 3).astype(np.float32)
    ).partition(np.full(rows, n)))

    if "attitude" in traces:             # the nonlinear vehicle: an oriented hull
        att = traces["attitude"][ks].reshape(rows * n, 3)
        rec.log(f"{root}/hulls", rr.Ellipsoids3D.from_fields(
            half_sizes=[_HULL_HALF_SIZES] * n, colors=colors, fill_mode="solid"), static=True)
        rec.send_columns(f"{root}/hulls", indexes=indexes, columns=rr.Ellipsoids3D.columns(
            centers=pos.reshape(rows * n, 3).astype(np.float32),
            quaternions=quaternion_xyzw(att).astype(np.float32)).partition(np.full(rows, n)))

    rec.log(f"{root}/leader", rr.Points3D.from_fields(
        radii=[1.5], colors=[(255, 215, 0)]), static=True)
    rec.log(f"{root}/leader_path", rr.LineStrips3D(
        [lead_all[::stride].astype(np.float32)], radii=[0.12], colors=[(230, 190, 0)]),
        static=True)
    rec.send_columns(f"{root}/leader", indexes=indexes, columns=rr.Points3D.columns(
        positions=leader.astype(np.float32)).partition(np.ones(rows, dtype=np.int64)))

    rec.log(f"{root}/targets", rr.Points3D.from_fields(
        radii=[0.7], colors=[tuple(_lighter(tuple(int(v) for v in c), 0.55)) for c in colors],
        show_labels=False), static=True)
    rec.send_columns(f"{root}/targets", indexes=indexes, columns=rr.Points3D.columns(
        positions=targets.reshape(rows * n, 3).astype(np.float32)).partition(np.full(rows, n)))

    n_edges, n_pinned = fleet.edges.shape[0], fleet.pinned.shape[0]
    n_seg = n_edges + n_pinned
    if n_seg:
        es = _sample_steps(steps, scene_stride, int(ks[-1]))
        e_rows = es.size
        seg = np.empty((e_rows, n_seg, 2, 3), dtype=np.float32)
        seg[:, :n_edges, 0] = pos_all[es][:, fleet.edges[:, 0]]
        seg[:, :n_edges, 1] = pos_all[es][:, fleet.edges[:, 1]]
        seg[:, n_edges:, 0] = lead_all[es][:, None, :]
        seg[:, n_edges:, 1] = pos_all[es][:, fleet.pinned]
        rec.log(f"{root}/edges", rr.LineStrips3D.from_fields(
            radii=[0.15], colors=[(160, 160, 160)] * n_edges + [(255, 215, 0)] * n_pinned),
            static=True)
        rec.send_columns(f"{root}/edges", indexes=_time_columns(es, h_ns),
                         columns=rr.LineStrips3D.columns(
                             strips=seg.reshape(e_rows * n_seg, 2, 3)
                         ).partition(np.full(e_rows, n_seg)))

    # Trails: one segment per vehicle from the previous trail sample to this one.
    ts = _sample_steps(steps, trail_stride, int(ks[-1]))
    if ts.size >= 2:
        t_rows = ts.size - 1
        seg = np.empty((t_rows, n, 2, 3), dtype=np.float32)
        seg[:, :, 0] = pos_all[ts[:-1]]
        seg[:, :, 1] = pos_all[ts[1:]]
        rec.log(f"{root}/trails", rr.LineStrips3D.from_fields(radii=[0.2]), static=True)
        rec.send_columns(f"{root}/trails", indexes=_time_columns(ts[1:], h_ns),
                         columns=rr.LineStrips3D.columns(
                             strips=seg.reshape(t_rows * n, 2, 3),
                             colors=np.tile(colors, (t_rows, 1)),
                         ).partition(np.full(t_rows, n)))


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
    stride = _positive_int(stride, "stride")
    if scene_stride is not None:
        scene_stride = _positive_int(scene_stride, "scene_stride")
        if scene_stride % stride:
            raise ValueError(f"write_rrd: scene_stride = {scene_stride} must be a multiple of "
                             f"stride = {stride}")
    path = Path(path)
    methods = list(clean)
    colors = method_color(methods)
    fleet_v: _Fleet | None = None
    if fleet is None:
        blueprint = _blueprint(clean)
    else:
        fleet_v = _validate_fleet(fleet, clean)
        trail_ns, sample_ns = (_positive_ns(v, name) for v, name in (
            (trail_seconds, "trail_seconds"), (trail_sample_seconds, "trail_sample_seconds")))
        trail_steps = -(-trail_ns // h_ns)  # ceil: the step range covers at least trail_seconds
        trail_stride = stride * max(1, round(sample_ns / (stride * h_ns)))
        if scene_stride is None:
            scene_stride = trail_stride
        with_links = {m: {**clean[m], **{k: np.asarray(runs[m][k]) for k in LINK_KEYS}}
                      if links and m in links else clean[m] for m in methods}
        blueprint = _fleet_blueprint(methods, fleet_v, trail_ns, trail_steps, with_links,
                                     links={m: list(v) for m, v in links.items()
                                            if m in clean} if links else None)

    t0 = time.perf_counter()
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream(application_id, recording_id=uuid.uuid4())
    if not rec.is_enabled():
        raise RuntimeError("write_rrd: Rerun logging is disabled (RERUN env var?); refusing to "
                           "write an empty .rrd")
    signals = 0
    tmp = path.with_name(f".{path.name}.{os.getpid()}.part")   # renamed when complete
    try:
        rec.save(tmp, default_blueprint=blueprint)
        rec.send_recording_name(recording_name)

        indexes = _time_columns(np.arange(0, steps, stride, dtype=np.int64), h_ns)
        if fleet_v is None:
            styles = method_styles(methods)
            for method in methods:
                base = colors[method]
                light = _lighter(base)
                width, alpha = styles[method].width, styles[method].viewer_alpha
                for key, template, suffix, is_estimate in _SERIES:
                    arr = clean[method][key]
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
            rec.log(LEGEND_ENTITY, rr.TextDocument(_paper_legend(methods, colors),
                                                   media_type=rr.MediaType.MARKDOWN), static=True)
        else:
            rec.log("world", rr.ViewCoordinates.FRD, static=True)
            rec.log(LEGEND_ENTITY, rr.TextDocument(_fleet_legend(
                methods, fleet_v, any("rpm" in clean[m] for m in methods)),
                                                   media_type=rr.MediaType.MARKDOWN), static=True)
            for index, method in enumerate(methods):
                signals += _send_fleet_series(rec, method, clean[method], fleet_v,
                                              index, stride, indexes, len(methods))
                _send_fleet_world(rec, method, clean[method], fleet_v, h_ns, stride,
                                  scene_stride, trail_stride)
                if links and method in links:
                    signals += send_links(rec, method, runs[method], links[method], stride,
                                          indexes, index, n=fleet_v.n)
            if links:
                rec.log(LINKS_LEGEND_ENTITY, rr.TextDocument(
                    links_legend([m for m in methods if m in links]),
                    media_type=rr.MediaType.MARKDOWN), static=True)
            if any("rpm" in clean[m] for m in methods):
                ends = np.array([0, (steps - 1) // stride * stride], dtype=np.int64)
                send_limits(rec, _time_columns(ends, h_ns), fleet_v.n_max or DEFAULT_N_MAX,
                            fleet_v.delta_max or DEFAULT_DELTA_MAX)
        rec.flush()
    except BaseException:
        rec.disconnect()
        del rec
        tmp.unlink(missing_ok=True)
        raise
    # Dropping the file sink finishes the file (footer + manifest) before returning.
    rec.disconnect()
    del rec
    os.replace(tmp, path)
    rrd_s = time.perf_counter() - t0
    return {"rrd_s": rrd_s, "signals": signals, "bytes": path.stat().st_size}
