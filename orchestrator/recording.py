"""Write simulation traces to a Rerun .rrd file (rerun-sdk 0.41) and read them back.

Layout of the file written by :func:`write_rrd` (components are 1-based, ``{m}`` is the
method name, e.g. ``kalman``, ``classical``, ``ideal``):

====================================  ==================  =================================
entity path                           trace               series name
====================================  ==================  =================================
``error/{i}/{m}``                     ``e[:, i-1]``       ``{m}``
``state/{i}/{m}/true``                ``x[:, i-1]``       ``{m}``
``state/{i}/{m}/estimate``            ``xhat[:, i-1]``    ``{m} estimate``
``control/{i}/{m}``                   ``u[:, i-1]``       ``{m}``
``disturbance/{i}/{m}/true``          ``w[:, i-1]``       ``{m}``
``disturbance/{i}/{m}/estimate``      ``what[:, i-1]``    ``{m} estimate``
``reference/{i}/{m}/true``            ``z[:, i-1]``       ``{m}``
``reference/{i}/{m}/estimate``        ``zhat[:, i-1]``    ``{m} estimate``
``measurement/y/{i}/{m}``             ``y[:, i-1]``       ``{m} y``
``measurement/ybar/{i}/{m}``          ``ybar[:, i-1]``    ``{m} ybar``
====================================  ==================  =================================

Every series is one ``rr.Scalars`` column sent with ``send_columns`` on two timelines:
``step`` (sequence, the sample index k) and ``sim_time`` (duration, k * round(h * 1e9)
integer nanoseconds, so no float rounding of the time axis).  Each entity also gets a
static ``rr.SeriesLines`` with its series name and colour.

The file embeds a default blueprint: a grid of time-series views ``error-i``, ``state-i``,
``control-i``, ``disturbance-i``, ``reference-i`` whose origins are ``/error/i`` etc., so each
view overlays every method (and the true/estimate pair) of that component.
"""
from __future__ import annotations

import time
import uuid
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb
from rerun.chunk import RrdReader

__all__ = [
    "TRACE_KEYS",
    "VIEW_GROUPS",
    "method_color",
    "write_rrd",
    "read_rrd_scalars",
    "read_rrd_series_styles",
    "read_rrd_blueprint_views",
    "rrd_has_blueprint",
]

#: Trace keys every run must provide (each an array of shape (steps, dim)).
TRACE_KEYS: tuple[str, ...] = ("x", "w", "z", "e", "u", "xhat", "what", "zhat", "y", "ybar")

# (trace key, entity path template, series-name suffix, is an estimate)
_SERIES: tuple[tuple[str, str, str, bool], ...] = (
    ("e", "error/{i}/{m}", "", False),
    ("x", "state/{i}/{m}/true", "", False),
    ("xhat", "state/{i}/{m}/estimate", " estimate", True),
    ("u", "control/{i}/{m}", "", False),
    ("w", "disturbance/{i}/{m}/true", "", False),
    ("what", "disturbance/{i}/{m}/estimate", " estimate", True),
    ("z", "reference/{i}/{m}/true", "", False),
    ("zhat", "reference/{i}/{m}/estimate", " estimate", True),
    ("y", "measurement/y/{i}/{m}", " y", False),
    ("ybar", "measurement/ybar/{i}/{m}", " ybar", False),
)

#: Blueprint view groups: (view name prefix == entity root, trace keys whose dims count).
VIEW_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("error", ("e",)),
    ("state", ("x", "xhat")),
    ("control", ("u",)),
    ("disturbance", ("w", "what")),
    ("reference", ("z", "zhat")),
)

_FIXED_COLORS: dict[str, tuple[int, int, int]] = {
    "kalman": (31, 119, 180),    # blue
    "classical": (255, 127, 14),  # orange
    "ideal": (44, 160, 44),       # green
}
_PALETTE: tuple[tuple[int, int, int], ...] = (
    (214, 39, 40),    # red
    (148, 103, 189),  # purple
    (140, 86, 75),    # brown
    (227, 119, 194),  # pink
    (127, 127, 127),  # grey
    (188, 189, 34),   # olive
    (23, 190, 207),   # cyan
)

_STEP = "step"
_SIM_TIME = "sim_time"
_SCALARS_COLUMN = "Scalars:scalars"


def _lighter(rgb: tuple[int, int, int], amount: float = 0.5) -> tuple[int, int, int]:
    """Blend an RGB colour towards white by ``amount`` (0: unchanged, 1: white)."""
    return tuple(int(round(c + (255 - c) * amount)) for c in rgb)  # type: ignore[return-value]


def method_color(methods: list[str] | tuple[str, ...]) -> dict[str, tuple[int, int, int]]:
    """Colour (RGB 0-255) per method: fixed for kalman/classical/ideal, palette otherwise.

    Unknown names take palette colours in the order they appear in ``methods``.
    """
    colors: dict[str, tuple[int, int, int]] = {}
    n_unknown = 0
    for m in methods:
        if m in _FIXED_COLORS:
            colors[m] = _FIXED_COLORS[m]
        else:
            colors[m] = _PALETTE[n_unknown % len(_PALETTE)]
            n_unknown += 1
    return colors


def _validate(runs: Mapping[str, Mapping[str, np.ndarray]], h: float) -> tuple[dict[str, dict[str, np.ndarray]], int, int]:
    """Check the runs and the step; return float64 traces, the step count and h in ns."""
    if not isinstance(runs, Mapping) or len(runs) == 0:
        raise ValueError("write_rrd: runs must be a non-empty mapping method -> traces")
    h = float(h)
    if not np.isfinite(h) or h <= 0.0:
        raise ValueError(f"write_rrd: step h must be a positive number of seconds, got {h!r}")
    h_ns = int(round(h * 1e9))
    if h_ns < 1:
        raise ValueError(f"write_rrd: step h={h!r} s is below one nanosecond")

    clean: dict[str, dict[str, np.ndarray]] = {}
    steps: int | None = None
    first: tuple[str, str] | None = None
    for method, traces in runs.items():
        if not isinstance(method, str) or not method or "/" in method or method.strip() != method:
            raise ValueError(f"write_rrd: method name {method!r} is not a valid entity path part "
                             "(non-empty, no '/', no surrounding spaces)")
        if not isinstance(traces, Mapping):
            raise ValueError(f"write_rrd: run {method!r} must be a mapping of traces, "
                             f"got {type(traces).__name__}")
        missing = [k for k in TRACE_KEYS if k not in traces]
        if missing:
            raise ValueError(f"write_rrd: run {method!r} is missing trace key(s) "
                             f"{', '.join(repr(k) for k in missing)} (needs {', '.join(TRACE_KEYS)})")
        clean[method] = {}
        for key in TRACE_KEYS:
            try:
                arr = np.asarray(traces[key], dtype=np.float64)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"write_rrd: run {method!r} trace {key!r} is not a float array: {exc}") from exc
            if arr.ndim != 2:
                raise ValueError(f"write_rrd: run {method!r} trace {key!r} must have shape (steps, dim), "
                                 f"got shape {arr.shape}")
            if steps is None:
                steps, first = arr.shape[0], (method, key)
            elif arr.shape[0] != steps:
                raise ValueError(f"write_rrd: run {method!r} trace {key!r} has {arr.shape[0]} steps, "
                                 f"but run {first[0]!r} trace {first[1]!r} has {steps}; "
                                 "all runs and traces must have the same number of steps")
            clean[method][key] = arr
    assert steps is not None
    if steps == 0:
        raise ValueError("write_rrd: traces have zero steps; nothing to write")
    return clean, steps, h_ns


def _blueprint(clean: dict[str, dict[str, np.ndarray]]) -> rrb.Blueprint:
    """Grid of one TimeSeriesView per (group, component), origin ``/{group}/{i}``."""
    views: list[rrb.TimeSeriesView] = []
    for group, keys in VIEW_GROUPS:
        dim = max(run[k].shape[1] for run in clean.values() for k in keys)
        for i in range(1, dim + 1):
            views.append(rrb.TimeSeriesView(name=f"{group}-{i}", origin=f"/{group}/{i}"))
    return rrb.Blueprint(
        rrb.Grid(contents=views, name="paper figures"),
        rrb.TimePanel(timeline=_SIM_TIME),
    )


def write_rrd(path: str | Path, runs: dict[str, dict[str, np.ndarray]], h: float, *,
              recording_name: str, application_id: str = "auv-cosim") -> dict[str, float]:
    """Write the traces of one or more runs to a Rerun .rrd file with a default blueprint.

    Parameters
    ----------
    path:
        Output .rrd file (overwritten).
    runs:
        Method name -> traces; each trace (keys :data:`TRACE_KEYS`) a float array of shape
        (steps, dim) in the simulation's own units (states, errors, references in the plant's
        units; controls in the actuator's units).  Row k is sample k, at time k*h seconds.
        All traces of all runs must have the same number of steps; dims may differ per key.
        Extra keys are ignored.
    h:
        Sampling period in seconds (> 0); stored as round(h * 1e9) integer nanoseconds.
    recording_name:
        Human-readable recording name shown by the viewer.
    application_id:
        Rerun application id (the default blueprint applies to this id).

    Returns
    -------
    dict with ``rrd_s`` (wall-clock seconds spent writing, validation excluded),
    ``signals`` (number of scalar series written, an int) and ``bytes`` (file size in
    bytes, an int).

    Raises
    ------
    ValueError
        If ``runs`` is empty, a run misses a trace key, a trace is not 2-D, step counts
        differ, a method name is not a valid entity path part, or ``h`` is not positive.
    RuntimeError
        If Rerun logging is disabled (e.g. ``RERUN=off``), since the file would be empty.
    """
    clean, steps, h_ns = _validate(runs, h)
    path = Path(path)
    methods = list(clean)
    colors = method_color(methods)
    blueprint = _blueprint(clean)

    t0 = time.perf_counter()
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream(application_id, recording_id=uuid.uuid4())
    if not rec.is_enabled():
        raise RuntimeError("write_rrd: Rerun logging is disabled (RERUN env var?); refusing to "
                           "write an empty .rrd")
    signals = 0
    try:
        rec.save(path, default_blueprint=blueprint)
        rec.send_recording_name(recording_name)

        k = np.arange(steps, dtype=np.int64)
        indexes = [
            rr.TimeColumn(_STEP, sequence=k),
            rr.TimeColumn(_SIM_TIME, duration=(k * h_ns).astype("timedelta64[ns]")),
        ]
        for method in methods:
            base = colors[method]
            light = _lighter(base)
            for key, template, suffix, is_estimate in _SERIES:
                arr = clean[method][key]
                style = rr.SeriesLines(colors=[light if is_estimate else base],
                                       names=[f"{method}{suffix}"])
                for i in range(1, arr.shape[1] + 1):
                    entity = template.format(i=i, m=method)
                    rec.log(entity, style, static=True)
                    rec.send_columns(
                        entity,
                        indexes=indexes,
                        columns=rr.Scalars.columns(scalars=np.ascontiguousarray(arr[:, i - 1])),
                    )
                    signals += 1
        rec.flush()
    finally:
        # Dropping the file sink finishes the file (footer + manifest) before returning.
        rec.disconnect()
        del rec
    rrd_s = time.perf_counter() - t0
    return {"rrd_s": rrd_s, "signals": signals, "bytes": path.stat().st_size}


def _int64_index(column: pa.Array | pa.ChunkedArray) -> np.ndarray:
    """An index column (int64 sequence or duration[ns]) as an int64 numpy array."""
    t = column.type
    if pa.types.is_duration(t):
        if t.unit != "ns":
            column = column.cast(pa.duration("ns"))
        column = column.cast(pa.int64())
    return np.asarray(column.to_numpy(zero_copy_only=False), dtype=np.int64)


def read_rrd_scalars(path: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Read every scalar series of the recording in a .rrd file, without a viewer.

    Returns entity path (no leading slash, e.g. ``error/1/kalman``) -> (step as int64,
    sim_time as int64 nanoseconds, values as float64), sorted by step.  Static data
    (series styles, recording properties) is skipped.
    """
    parts: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
    for chunk in RrdReader(path).stream():
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if _SCALARS_COLUMN not in names:
            continue
        entity = chunk.entity_path.lstrip("/")
        if _STEP not in names or _SIM_TIME not in names:
            raise ValueError(f"{path}: scalar chunk of {entity!r} lacks the step/sim_time timelines")
        scal = batch.column(_SCALARS_COLUMN)
        lengths = np.asarray(scal.value_lengths().fill_null(0).to_numpy(zero_copy_only=False))
        if not np.all(lengths == 1):
            raise ValueError(f"{path}: {entity!r} has rows with other than one scalar")
        values = np.asarray(scal.flatten().to_numpy(zero_copy_only=False), dtype=np.float64)
        parts.setdefault(entity, []).append(
            (_int64_index(batch.column(_STEP)), _int64_index(batch.column(_SIM_TIME)), values))

    out: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    for entity, pieces in parts.items():
        step = np.concatenate([p[0] for p in pieces])
        sim_time = np.concatenate([p[1] for p in pieces])
        values = np.concatenate([p[2] for p in pieces])
        order = np.argsort(step, kind="stable")
        out[entity] = (step[order], sim_time[order], values[order])
    return out


def read_rrd_series_styles(path: str | Path) -> dict[str, tuple[str, tuple[int, int, int, int]]]:
    """Static series styles of a .rrd: entity path -> (series name, RGBA colour 0-255)."""
    out: dict[str, tuple[str, tuple[int, int, int, int]]] = {}
    for chunk in RrdReader(path).stream():
        if not chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if "SeriesLines:names" not in names or "SeriesLines:colors" not in names:
            continue
        entity = chunk.entity_path.lstrip("/")
        name = batch.column("SeriesLines:names").to_pylist()[-1][0]
        packed = int(batch.column("SeriesLines:colors").to_pylist()[-1][0])  # 0xRRGGBBAA
        rgba = ((packed >> 24) & 0xFF, (packed >> 16) & 0xFF, (packed >> 8) & 0xFF, packed & 0xFF)
        out[entity] = (name, rgba)
    return out


def read_rrd_blueprint_views(path: str | Path) -> dict[str, tuple[str, str]]:
    """Views of the blueprint(s) embedded in a .rrd: view name -> (view class, origin).

    The view class is Rerun's identifier, e.g. ``TimeSeries``; the origin is the entity
    path with its leading slash, e.g. ``/error/1``.  Empty if no blueprint is embedded.
    """
    reader = RrdReader(path)
    views: dict[str, tuple[str, str]] = {}
    for store in reader.blueprints():
        for chunk in reader.stream(store=store):
            batch = chunk.to_record_batch()
            cols = batch.schema.names
            if "ViewBlueprint:display_name" not in cols:
                continue
            names = batch.column("ViewBlueprint:display_name").to_pylist()
            classes = (batch.column("ViewBlueprint:class_identifier").to_pylist()
                       if "ViewBlueprint:class_identifier" in cols else [[""]] * len(names))
            origins = (batch.column("ViewBlueprint:space_origin").to_pylist()
                       if "ViewBlueprint:space_origin" in cols else [["/"]] * len(names))
            for n, c, o in zip(names, classes, origins):
                if n:
                    views[n[0]] = (c[0] if c else "", o[0] if o else "/")
    return views


def rrd_has_blueprint(path: str | Path) -> bool:
    """True if the .rrd embeds a blueprint store with at least one view."""
    return bool(read_rrd_blueprint_views(path))
