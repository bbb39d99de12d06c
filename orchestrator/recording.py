"""Write simulation traces to a Rerun .rrd file (rerun-sdk 0.41) and read them back.

Two layouts: the per-component ("paper") layout below, written when no ``fleet`` is given,
and the compact per-vehicle fleet layout further down, written *instead* when a
:class:`FleetLayout` is given.

Paper layout (no ``fleet``; components are 1-based, ``{m}`` is the method name, e.g.
``kalman``, ``classical``, ``ideal``):

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

Decimation (``stride``, both layouts)
-------------------------------------
Only the steps k = 0, stride, 2*stride, ... (k < steps) are recorded; the time columns still
hold the true step index k and k * round(h * 1e9) ns, so a reader sees the true times.  The
last step is recorded only if it falls on the stride.  ``stride=1`` (default) records every
step.

Fleet of N vehicles (``write_rrd(..., fleet=FleetLayout(...))``)
-----------------------------------------------------------------
The paper layout above is *not* written (at N = 20 it is hundreds of one-scalar series, and
most of the file).  Instead every vehicle gets a few multi-component entities: one
``send_columns`` per entity whose ``rr.Scalars`` rows hold all components of that vehicle
(row k = the k-th recorded step), and a static ``rr.SeriesLines`` with one name and colour
per component, so the viewer draws each component as its own line.  Vehicles ``i`` / ``j``
are 1-based, ``{m}`` is the method, ``E`` = ``error_index[i-1]``, ``C`` = ``control_index[i-1]``,
``S`` = ``state_index[i-1]``, ``D`` = ``disturbance_index[i-1]``, ``L`` = ``leader_output``,
``p_i(k)`` = ``x[k, position_index[i-1]]``, the vehicle's north, east, down position in m:

=======================================  ===============  ========================================
entity path                              archetype        content per recorded step k
=======================================  ===============  ========================================
``vehicles/{i}/error/{m}``               Scalars          ``e[k, E]``; lines ``{m} {error name}``
``vehicles/{i}/control/{m}``             Scalars          ``u[k, C]``; lines ``{m} {control name}``
``vehicles/{i}/state/{m}/true``          Scalars          ``x[k, S]``; lines ``{m} {state name}``
``vehicles/{i}/state/{m}/estimate``      Scalars          ``xhat[k, S]``; lines
                                                          ``{m} {state name} estimate``
``vehicles/{i}/current/{m}/true``        Scalars          ``w[k, D]``; lines ``{m} {disturbance
                                                          name}`` (only if ``disturbance_index``)
``vehicles/{i}/current/{m}/estimate``    Scalars          ``what[k, D]``; lines ``... estimate``
``leader/{m}``                           Scalars          ``L @ z[k]`` (3 values); lines
                                                          ``{m} leader north|east|down``
``world``, ``world/{m}``                 ViewCoordinates  static ``FRD``: x north, y east, z down
``world/{m}/vehicles``                   Points3D         N points ``p_1(k) .. p_N(k)``, labels
                                                          ``"1" .. "N"``, radius 1 m
``world/{m}/leader``                     Points3D         1 point ``L @ z[k]``, label ``leader``
``world/{m}/targets``                    Points3D         N points ``L @ z[k] + offsets[i-1]``
``world/{m}/edges``                      LineStrips3D     one segment ``[p_j(k), p_i(k)]`` per edge
                                                          ``(j, i)`` (in ``edges`` order), then one
                                                          ``[L @ z[k], p_i(k)]`` per pinned ``i``;
                                                          only every ``scene_stride`` steps
``world/{m}/trails``                     LineStrips3D     N segments ``[p_i(k'), p_i(k)]``, only
                                                          every trail stride steps (k' the
                                                          previous trail sample)
=======================================  ===============  ========================================

Colours: component c of a method takes shade c of the method colour (the colour itself, then
darker / lighter shades), estimates a lighter version of the same shade, so the components of
one method stay apart inside one view.  ``read_rrd_series`` / ``read_rrd_scalars`` read the
(rows, k) values back; ``read_rrd_series_lines`` the per-component names and colours.

3D scene.  All 3D entities are sent with ``send_columns`` (one partition per sample) on both
timelines; styles (colours, radii, labels) are static.  Rerun stores 3D positions as float32,
so what is read back equals the float64 positions cast to float32.  ``vehicles``, ``leader``
and ``targets`` are written at every recorded step.  The slow, bulky parts are decimated:

* trails: one segment per vehicle every *trail stride* =
  stride * max(1, round(trail_sample_seconds / (stride * h))) steps (default
  ``trail_sample_seconds`` 0.5 s), plus the last recorded step;
* edges: every ``scene_stride`` steps (default: the trail stride; a multiple of ``stride``),
  plus the last recorded step.  Between two edge samples the viewer shows the latest one, so
  the edges may lag the vehicle points by up to ``scene_stride`` steps.

The 3D view shows the trails through a per-entity visible time range
``[cursor - trail_seconds, cursor]`` on both ``sim_time`` and ``step`` (the other 3D entities
show the latest sample at the cursor), so the trail follows the time cursor.

Default blueprint with a fleet: ``Horizontal[left, right]``.  Left: the 3D view ``fleet {m}``
(origin ``/world/{m}``) of the first method, or ``Tabs`` of one such view per method (first
active).  Right: views ``vehicle i error`` (origin ``/vehicles/i/error``) and ``vehicle i
control`` (origin ``/vehicles/i/control``), each overlaying every method, in a two-column
``Grid`` for N <= 8, or, for N > 8, ``Tabs`` of such grids, one tab ``vehicles a-b`` per group
of 4 vehicles.  State, current and leader entities are in the file but not in the default
views (drag them into a view in the viewer).
"""
from __future__ import annotations

import colorsys
import time
import uuid
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb
from rerun.chunk import RrdReader

__all__ = [
    "TRACE_KEYS",
    "VIEW_GROUPS",
    "FleetLayout",
    "method_color",
    "read_rrd_blueprint_tree",
    "read_rrd_blueprint_views",
    "read_rrd_line_strips",
    "read_rrd_points",
    "read_rrd_scalars",
    "read_rrd_series",
    "read_rrd_series_lines",
    "read_rrd_series_styles",
    "read_rrd_visible_time_ranges",
    "rrd_has_blueprint",
    "write_rrd",
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
#: Names of the three NED position components (leader series, default state names).
_POSITION_NAMES: tuple[str, ...] = ("north", "east", "down")


def _lighter(rgb: tuple[int, int, int], amount: float = 0.5) -> tuple[int, int, int]:
    """Blend an RGB colour towards white by ``amount`` (0: unchanged, 1: white)."""
    return tuple(round(c + (255 - c) * amount) for c in rgb)  # type: ignore[return-value]


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


@dataclass(frozen=True, eq=False)
class FleetLayout:
    """Where the N vehicles of a fleet live in the traces, for the fleet entities and views.

    Vehicle i (1-based) is row i-1 of every array.  Arrays may be given as lists; they are
    checked against the traces (and copied) by :func:`write_rrd`, which raises ValueError
    naming the field at fault.  ``eq=False``: layouts compare by identity (numpy fields).
    """

    #: (N, 3) int: columns of x holding the north, east, down position (m, NED) of vehicle i.
    position_index: np.ndarray
    #: (N, s) int: columns of e belonging to vehicle i, in the order of ``error_names``.
    error_index: np.ndarray
    #: (N, q) int: columns of u belonging to vehicle i, in the order of ``control_names``.
    control_index: np.ndarray
    #: s labels of the error components, e.g. ("north", "east", "down").
    error_names: tuple[str, ...]
    #: q labels of the control components, e.g. ("X_n", "X_e", "X_d").
    control_names: tuple[str, ...]
    #: (3, l): leader position (NED, m) = leader_output @ z[k].
    leader_output: np.ndarray
    #: (N, 3): formation offset of vehicle i; its target is leader position + offset.
    offsets: np.ndarray
    #: Communication edges (j, i), 1-based: vehicle i hears vehicle j.
    edges: tuple[tuple[int, int], ...]
    #: 1-based vehicles that hear the leader.
    pinned: tuple[int, ...]
    #: (N, p) int: columns of x (and xhat) belonging to vehicle i, in the order of
    #: ``state_names`` (the position columns and the vehicle's other states).  None: the
    #: ``position_index`` columns, named ``state_names`` or ("north", "east", "down").
    state_index: np.ndarray | None = None
    #: p labels of the state components, e.g. ("north", "east", "down", "u", "v", "w").
    state_names: tuple[str, ...] | None = None
    #: (N, r) int: columns of w (and what) belonging to vehicle i, in the order of
    #: ``disturbance_names`` (e.g. the vehicle's current states).  None: no current entities.
    disturbance_index: np.ndarray | None = None
    #: r labels of the disturbance components, e.g. ("n", "e", "d").
    disturbance_names: tuple[str, ...] | None = None

    @property
    def n_vehicles(self) -> int:
        """Number of vehicles N (rows of ``position_index``)."""
        return int(np.shape(self.position_index)[0])


@dataclass(frozen=True)
class _Fleet:
    """A FleetLayout after validation: numpy arrays of fixed dtype, 0-based edge ends."""

    n: int
    position_index: np.ndarray   # (N, 3) int64
    error_index: np.ndarray      # (N, s) int64
    control_index: np.ndarray    # (N, q) int64
    error_names: tuple[str, ...]
    control_names: tuple[str, ...]
    leader_output: np.ndarray    # (3, l) float64
    offsets: np.ndarray          # (N, 3) float64
    edges: np.ndarray            # (E, 2) int64, 0-based (j, i)
    pinned: np.ndarray           # (P,) int64, 0-based
    state_index: np.ndarray      # (N, p) int64
    state_names: tuple[str, ...]
    disturbance_index: np.ndarray | None  # (N, r) int64, or None: no current entities
    disturbance_names: tuple[str, ...]


def _index_array(value: object, field: str, cols: int | None) -> np.ndarray:
    """A 2-D integer array (N, cols) from a FleetLayout field, or ValueError naming it."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "iu":
        raise ValueError(f"write_rrd: fleet.{field} must be an integer array, got dtype {arr.dtype}")
    if arr.ndim != 2 or (cols is not None and arr.shape[1] != cols) or arr.shape[1] < 1:
        want = f"(N, {cols})" if cols is not None else "(N, k) with k >= 1"
        raise ValueError(f"write_rrd: fleet.{field} must have shape {want}, got shape {arr.shape}")
    return arr.astype(np.int64)


def _check_columns(arr: np.ndarray, field: str, clean: dict[str, dict[str, np.ndarray]], key: str) -> None:
    """Every entry of an index array must be a column of trace ``key`` in every run."""
    for method, traces in clean.items():
        dim = traces[key].shape[1]
        bad = np.argwhere((arr < 0) | (arr >= dim))
        if bad.size:
            r, c = (int(v) for v in bad[0])
            raise ValueError(f"write_rrd: fleet.{field}[{r}, {c}] = {int(arr[r, c])} (vehicle {r + 1}) is "
                             f"out of range for run {method!r} trace {key!r}, which has {dim} columns "
                             f"(valid 0..{dim - 1})")


def _check_names(names: object, field: str, count: int, index_field: str) -> tuple[str, ...]:
    """Component labels: ``count`` distinct, non-empty entity path parts."""
    if isinstance(names, str) or not isinstance(names, (tuple, list)):
        raise ValueError(f"write_rrd: fleet.{field} must be a tuple of strings, got {names!r}")  # noqa: TRY004
    names = tuple(names)
    if len(names) != count:
        raise ValueError(f"write_rrd: fleet.{field} has {len(names)} labels, but fleet.{index_field} "
                         f"has {count} columns per vehicle")
    for n in names:
        if not isinstance(n, str) or not n or "/" in n or n.strip() != n:
            raise ValueError(f"write_rrd: fleet.{field} label {n!r} is not a valid entity path part "
                             "(non-empty string, no '/', no surrounding spaces)")
    if len(set(names)) != len(names):
        raise ValueError(f"write_rrd: fleet.{field} labels must be distinct, got {names!r}")
    return names


def _vehicle_number(v: object, n: int, where: str) -> int:
    """A 1-based vehicle number in 1..n, returned 0-based, or ValueError naming ``where``."""
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
        raise ValueError(f"write_rrd: {where} = {v!r} is not an integer vehicle number")  # noqa: TRY004
    if not 1 <= int(v) <= n:
        raise ValueError(f"write_rrd: {where} names vehicle {int(v)}, which does not exist: the fleet "
                         f"has N = {n} vehicles, numbered 1..{n}")
    return int(v) - 1


def _validate_fleet(fleet: FleetLayout, clean: dict[str, dict[str, np.ndarray]]) -> _Fleet:
    """Check a FleetLayout against the (validated) traces of every run."""
    if not isinstance(fleet, FleetLayout):
        raise ValueError(f"write_rrd: fleet must be a FleetLayout, got {type(fleet).__name__}")  # noqa: TRY004
    pos = _index_array(fleet.position_index, "position_index", 3)
    n = pos.shape[0]
    if n < 1:
        raise ValueError("write_rrd: fleet.position_index has no rows: the fleet has no vehicles")
    err = _index_array(fleet.error_index, "error_index", None)
    ctl = _index_array(fleet.control_index, "control_index", None)
    sta = pos if fleet.state_index is None else _index_array(fleet.state_index, "state_index", None)
    dis = None if fleet.disturbance_index is None else _index_array(
        fleet.disturbance_index, "disturbance_index", None)
    for arr, field in ((err, "error_index"), (ctl, "control_index"), (sta, "state_index"),
                       (dis, "disturbance_index")):
        if arr is not None and arr.shape[0] != n:
            raise ValueError(f"write_rrd: fleet.{field} has {arr.shape[0]} rows, but fleet.position_index "
                             f"has {n} (one row per vehicle)")
    _check_columns(pos, "position_index", clean, "x")
    _check_columns(err, "error_index", clean, "e")
    _check_columns(ctl, "control_index", clean, "u")
    if fleet.state_index is not None:
        _check_columns(sta, "state_index", clean, "x")
    _check_columns(sta, "state_index" if fleet.state_index is not None else "position_index", clean, "xhat")
    error_names = _check_names(fleet.error_names, "error_names", err.shape[1], "error_index")
    control_names = _check_names(fleet.control_names, "control_names", ctl.shape[1], "control_index")
    if fleet.state_index is None and fleet.state_names is None:
        state_names: tuple[str, ...] = _POSITION_NAMES
    else:
        state_names = _check_names(fleet.state_names, "state_names", sta.shape[1],
                                   "state_index" if fleet.state_index is not None else "position_index")
    disturbance_names: tuple[str, ...] = ()
    if dis is not None:
        _check_columns(dis, "disturbance_index", clean, "w")
        _check_columns(dis, "disturbance_index", clean, "what")
        disturbance_names = _check_names(fleet.disturbance_names, "disturbance_names", dis.shape[1],
                                         "disturbance_index")
    elif fleet.disturbance_names is not None:
        raise ValueError("write_rrd: fleet.disturbance_names is given without fleet.disturbance_index")

    try:
        lead = np.asarray(fleet.leader_output, dtype=np.float64)
        offsets = np.asarray(fleet.offsets, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"write_rrd: fleet.leader_output / fleet.offsets must be float arrays: {exc}") from exc
    for method, traces in clean.items():
        l_dim = traces["z"].shape[1]
        if lead.shape != (3, l_dim):
            raise ValueError(f"write_rrd: fleet.leader_output must have shape (3, l) = (3, {l_dim}) to map "
                             f"run {method!r} trace 'z' ({l_dim} columns) to a position, got shape {lead.shape}")
    if not np.all(np.isfinite(lead)):
        raise ValueError("write_rrd: fleet.leader_output has non-finite entries")
    if offsets.shape != (n, 3):
        raise ValueError(f"write_rrd: fleet.offsets must have shape (N, 3) = ({n}, 3), got shape {offsets.shape}")
    if not np.all(np.isfinite(offsets)):
        raise ValueError("write_rrd: fleet.offsets has non-finite entries")

    edges: list[tuple[int, int]] = []
    for e, edge in enumerate(fleet.edges):
        if isinstance(edge, str) or not hasattr(edge, "__len__") or len(edge) != 2:
            raise ValueError(f"write_rrd: fleet.edges[{e}] = {edge!r} is not a pair (j, i)")
        j = _vehicle_number(edge[0], n, f"fleet.edges[{e}] = {tuple(edge)!r}")
        i = _vehicle_number(edge[1], n, f"fleet.edges[{e}] = {tuple(edge)!r}")
        if i == j:
            raise ValueError(f"write_rrd: fleet.edges[{e}] = {tuple(edge)!r} is a self-loop")
        edges.append((j, i))
    pinned = [_vehicle_number(v, n, f"fleet.pinned[{p}]") for p, v in enumerate(fleet.pinned)]
    return _Fleet(
        n=n, position_index=pos, error_index=err, control_index=ctl,
        error_names=error_names, control_names=control_names,
        leader_output=lead.copy(), offsets=offsets.copy(),
        edges=np.asarray(edges, dtype=np.int64).reshape(-1, 2),
        pinned=np.asarray(pinned, dtype=np.int64),
        state_index=sta, state_names=state_names,
        disturbance_index=dis, disturbance_names=disturbance_names,
    )


def _shade(rgb: tuple[int, int, int], k: int) -> tuple[int, int, int]:
    """Shade k of a colour: 0 the colour itself, then alternately darker and lighter."""
    if k == 0:
        return rgb
    amount = min(0.25 + 0.1 * ((k + 1) // 2), 0.7)
    if k % 2:  # darker: blend towards black
        return tuple(round(c * (1.0 - amount)) for c in rgb)  # type: ignore[return-value]
    return _lighter(rgb, amount)


def _vehicle_colors(n: int) -> np.ndarray:
    """(n, 3) uint8: one hue per vehicle, evenly spread round the colour wheel."""
    rgb = [colorsys.hsv_to_rgb(i / n, 0.75, 0.95) for i in range(n)]
    return np.round(np.asarray(rgb) * 255.0).astype(np.uint8).reshape(n, 3)


def _validate(runs: Mapping[str, Mapping[str, np.ndarray]], h: float) -> tuple[dict[str, dict[str, np.ndarray]], int, int]:
    """Check the runs and the step; return float64 traces, the step count and h in ns."""
    if not isinstance(runs, Mapping) or len(runs) == 0:
        raise ValueError("write_rrd: runs must be a non-empty mapping method -> traces")
    h = float(h)
    if not np.isfinite(h) or h <= 0.0:
        raise ValueError(f"write_rrd: step h must be a positive number of seconds, got {h!r}")
    h_ns = round(h * 1e9)
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
            raise ValueError(f"write_rrd: run {method!r} must be a mapping of traces, "  # noqa: TRY004
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


#: Vehicles per tab of the right-hand side of the fleet blueprint when N > _FLEET_GRID_MAX.
_FLEET_TAB_SIZE = 4
_FLEET_GRID_MAX = 8


def _trail_time_ranges(trail_ns: int, trail_steps: int) -> rrb.VisibleTimeRanges:
    """Visible range [cursor - trail, cursor] on both timelines."""
    return rrb.VisibleTimeRanges([
        rrb.VisibleTimeRange(_SIM_TIME, start=rrb.TimeRangeBoundary.cursor_relative(nanos=-trail_ns),
                             end=rrb.TimeRangeBoundary.cursor_relative()),
        rrb.VisibleTimeRange(_STEP, start=rrb.TimeRangeBoundary.cursor_relative(seq=-trail_steps),
                             end=rrb.TimeRangeBoundary.cursor_relative()),
    ])


def _positive_ns(value: object, name: str) -> int:
    """A positive finite duration in seconds as integer nanoseconds (>= 1), or ValueError."""
    try:
        seconds = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        seconds = float("nan")
    if isinstance(value, (bool, np.bool_)) or not np.isfinite(seconds) or seconds <= 0.0:
        raise ValueError(f"write_rrd: {name} must be a positive number of seconds, got {value!r}")
    return max(1, round(seconds * 1e9))


def _fleet_blueprint(methods: list[str], n: int, trail_ns: int, trail_steps: int) -> rrb.Blueprint:
    """3D view(s) of the fleet on the left, per-vehicle error/control views on the right."""
    views_3d = [
        rrb.Spatial3DView(
            name=f"fleet {m}",
            origin=f"/world/{m}",
            overrides={f"/world/{m}/trails": _trail_time_ranges(trail_ns, trail_steps)},
        )
        for m in methods
    ]
    left: rrb.Container | rrb.View = (
        views_3d[0] if len(views_3d) == 1 else rrb.Tabs(*views_3d, active_tab=0, name="fleet 3D"))

    def vehicle_views(i: int) -> list[rrb.TimeSeriesView]:
        return [rrb.TimeSeriesView(name=f"vehicle {i} error", origin=f"/vehicles/{i}/error"),
                rrb.TimeSeriesView(name=f"vehicle {i} control", origin=f"/vehicles/{i}/control")]

    if n <= _FLEET_GRID_MAX:
        right: rrb.Container = rrb.Grid(
            contents=[v for i in range(1, n + 1) for v in vehicle_views(i)], grid_columns=2, name="vehicles")
    else:
        tabs = []
        for a in range(1, n + 1, _FLEET_TAB_SIZE):
            b = min(a + _FLEET_TAB_SIZE - 1, n)
            tabs.append(rrb.Grid(contents=[v for i in range(a, b + 1) for v in vehicle_views(i)],
                                 grid_columns=2, name=f"vehicles {a}-{b}"))
        right = rrb.Tabs(*tabs, active_tab=0, name="vehicles")
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=[1.0, 1.0], name="fleet"),
        rrb.TimePanel(timeline=_SIM_TIME),
    )


def _send_block(rec: rr.RecordingStream, entity: str, values: np.ndarray, names: list[str],
                colors: list[tuple[int, int, int]], indexes: list[rr.TimeColumn]) -> int:
    """One multi-component series entity: static SeriesLines (one name/colour per column of
    ``values``) and one ``send_columns`` whose rows hold all k components.  Returns k."""
    rec.log(entity, rr.SeriesLines(colors=colors, names=names), static=True)
    rec.send_columns(entity, indexes=indexes,
                     columns=rr.Scalars.columns(scalars=np.ascontiguousarray(values, dtype=np.float64)))
    return values.shape[1]


def _send_fleet_series(rec: rr.RecordingStream, method: str, traces: dict[str, np.ndarray], fleet: _Fleet,
                       base: tuple[int, int, int], stride: int, indexes: list[rr.TimeColumn]) -> int:
    """Per-vehicle multi-component series and the leader series of one run (recorded steps
    only); returns the number of scalar lines (components) written."""
    rec_traces = {key: traces[key][::stride] for key in ("e", "u", "x", "xhat", "w", "what", "z")}

    def shades(count: int, estimate: bool = False) -> list[tuple[int, int, int]]:
        return [_lighter(_shade(base, c)) if estimate else _shade(base, c) for c in range(count)]

    groups: list[tuple[str, str, np.ndarray, tuple[str, ...], str, bool]] = [
        ("e", "error/{m}", fleet.error_index, fleet.error_names, "", False),
        ("u", "control/{m}", fleet.control_index, fleet.control_names, "", False),
        ("x", "state/{m}/true", fleet.state_index, fleet.state_names, "", False),
        ("xhat", "state/{m}/estimate", fleet.state_index, fleet.state_names, " estimate", True),
    ]
    if fleet.disturbance_index is not None:
        groups += [
            ("w", "current/{m}/true", fleet.disturbance_index, fleet.disturbance_names, "", False),
            ("what", "current/{m}/estimate", fleet.disturbance_index, fleet.disturbance_names, " estimate", True),
        ]
    signals = 0
    for key, template, index, names, suffix, is_estimate in groups:
        arr = rec_traces[key]
        line_names = [f"{method} {name}{suffix}" for name in names]
        colors = shades(len(names), is_estimate)
        for i in range(1, fleet.n + 1):
            signals += _send_block(rec, f"vehicles/{i}/{template.format(m=method)}", arr[:, index[i - 1]],
                                   line_names, colors, indexes)
    leader = rec_traces["z"] @ fleet.leader_output.T  # (rows, 3)
    signals += _send_block(rec, f"leader/{method}", leader, [f"{method} leader {c}" for c in _POSITION_NAMES],
                           shades(3), indexes)
    return signals


def _time_columns(k: np.ndarray, h_ns: int) -> list[rr.TimeColumn]:
    return [rr.TimeColumn(_STEP, sequence=k),
            rr.TimeColumn(_SIM_TIME, duration=(k * h_ns).astype("timedelta64[ns]"))]


def _sample_steps(steps: int, every: int, last: int) -> np.ndarray:
    """Steps 0, every, 2*every, ... (< steps), then ``last`` if it is not among them."""
    ks = np.arange(0, steps, every, dtype=np.int64)
    if ks[-1] != last:
        ks = np.append(ks, last)
    return ks


def _send_fleet_world(rec: rr.RecordingStream, method: str, traces: dict[str, np.ndarray], fleet: _Fleet,
                      h_ns: int, stride: int, scene_stride: int, trail_stride: int) -> None:
    """The 3D scene of one run under ``world/{method}``: one partition per sample, no per-step logs."""
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
        radii=[1.0], colors=colors, labels=[str(i) for i in range(1, n + 1)], show_labels=True), static=True)
    rec.send_columns(f"{root}/vehicles", indexes=indexes, columns=rr.Points3D.columns(
        positions=pos.reshape(rows * n, 3).astype(np.float32)).partition(np.full(rows, n)))

    rec.log(f"{root}/leader", rr.Points3D.from_fields(
        radii=[1.5], colors=[(255, 215, 0)], labels=["leader"], show_labels=True), static=True)
    rec.send_columns(f"{root}/leader", indexes=indexes, columns=rr.Points3D.columns(
        positions=leader.astype(np.float32)).partition(np.ones(rows, dtype=np.int64)))

    rec.log(f"{root}/targets", rr.Points3D.from_fields(
        radii=[0.5], colors=[tuple(_lighter(tuple(int(v) for v in c), 0.6)) for c in colors],
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
            radii=[0.15], colors=[(160, 160, 160)] * n_edges + [(255, 215, 0)] * n_pinned), static=True)
        rec.send_columns(f"{root}/edges", indexes=_time_columns(es, h_ns), columns=rr.LineStrips3D.columns(
            strips=seg.reshape(e_rows * n_seg, 2, 3)).partition(np.full(e_rows, n_seg)))

    # Trails: one segment per vehicle from the previous trail sample to this one.
    ts = _sample_steps(steps, trail_stride, int(ks[-1]))
    if ts.size >= 2:
        t_rows = ts.size - 1
        seg = np.empty((t_rows, n, 2, 3), dtype=np.float32)
        seg[:, :, 0] = pos_all[ts[:-1]]
        seg[:, :, 1] = pos_all[ts[1:]]
        rec.log(f"{root}/trails", rr.LineStrips3D.from_fields(radii=[0.2]), static=True)
        rec.send_columns(f"{root}/trails", indexes=_time_columns(ts[1:], h_ns), columns=rr.LineStrips3D.columns(
            strips=seg.reshape(t_rows * n, 2, 3), colors=np.tile(colors, (t_rows, 1))).partition(np.full(t_rows, n)))


def _positive_int(value: object, name: str) -> int:
    """A positive integer (Python or numpy int, not bool), or ValueError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or int(value) < 1:
        raise ValueError(f"write_rrd: {name} must be a positive integer number of steps, got {value!r}")
    return int(value)


def write_rrd(path: str | Path, runs: dict[str, dict[str, np.ndarray]], h: float, *,
              recording_name: str, application_id: str = "auv-cosim",
              fleet: FleetLayout | None = None, trail_seconds: float = 60.0,
              trail_sample_seconds: float = 0.5, stride: int = 1,
              scene_stride: int | None = None) -> dict[str, float]:
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
    fleet:
        If given, the traces are those of a fleet of N vehicles laid out as described by the
        :class:`FleetLayout`; the compact per-vehicle layout and a 3D scene per run are
        written *instead of* the per-component layout, and the default blueprint becomes the
        fleet layout (see the module docstring).  Checked against the traces of every run.
    trail_seconds:
        Length (s, > 0) of the vehicle trails in the 3D view: the trail entity is shown over
        the visible time range [cursor - trail_seconds, cursor].  Only used with ``fleet``.
    trail_sample_seconds:
        Spacing (s, > 0) of the trail samples: one trail segment per vehicle every
        stride * max(1, round(trail_sample_seconds / (stride * h))) steps (plus the last
        recorded step).  Only used with ``fleet``.
    stride:
        Record only every stride-th step (k = 0, stride, 2*stride, ...), a positive int.  The
        time columns keep the true step index and sim_time.  Default 1: every step.
    scene_stride:
        Steps between two samples of the 3D edges (``world/{m}/edges``), a positive multiple
        of ``stride``; default (None) the trail stride.  Only used with ``fleet``.

    Returns
    -------
    dict with ``rrd_s`` (wall-clock seconds spent writing, validation excluded),
    ``signals`` (number of scalar series written, an int: one per entity in the paper layout,
    one per component, i.e. per line, of each multi-component entity in the fleet layout) and
    ``bytes`` (file size in bytes, an int).

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
    clean, steps, h_ns = _validate(runs, h)
    stride = _positive_int(stride, "stride")
    if scene_stride is not None:
        scene_stride = _positive_int(scene_stride, "scene_stride")
        if scene_stride % stride:
            raise ValueError(f"write_rrd: scene_stride = {scene_stride} must be a multiple of stride = {stride}")
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
        blueprint = _fleet_blueprint(methods, fleet_v.n, trail_ns, trail_steps)

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

        indexes = _time_columns(np.arange(0, steps, stride, dtype=np.int64), h_ns)
        if fleet_v is None:
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
                            columns=rr.Scalars.columns(scalars=np.ascontiguousarray(arr[::stride, i - 1])),
                        )
                        signals += 1
        else:
            rec.log("world", rr.ViewCoordinates.FRD, static=True)
            for method in methods:
                signals += _send_fleet_series(rec, method, clean[method], fleet_v, colors[method], stride, indexes)
                _send_fleet_world(rec, method, clean[method], fleet_v, h_ns, stride, scene_stride, trail_stride)
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


def _scalar_rows(scal: pa.Array, what: str) -> np.ndarray:
    """A ``Scalars:scalars`` list column whose rows all hold k values as a (rows, k) float64 array."""
    k = _uniform(_lengths(scal), f"{what}: scalars per row")
    values = np.asarray(scal.flatten().to_numpy(zero_copy_only=False), dtype=np.float64)
    if values.size != len(scal) * k:  # null rows
        raise ValueError(f"{what}: has empty (null) rows")
    return values.reshape(len(scal), k)


def _merge_rows(pieces: list[tuple[np.ndarray, np.ndarray, np.ndarray]], what: str
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Concatenate (step, sim_time, values (rows, k)) pieces and sort them by step."""
    _uniform(np.asarray([p[2].shape[1] for p in pieces]), f"{what}: scalars per row")
    step = np.concatenate([p[0] for p in pieces])
    sim_time = np.concatenate([p[1] for p in pieces])
    values = np.concatenate([p[2] for p in pieces])
    order = np.argsort(step, kind="stable")
    return step[order], sim_time[order], values[order]


def read_rrd_scalars(path: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Read every scalar series of the recording in a .rrd file, without a viewer.

    Returns entity path (no leading slash, e.g. ``error/1/kalman``) -> (step as int64,
    sim_time as int64 nanoseconds, values as float64), sorted by step.  Values are 1-D
    (rows,) for entities with one scalar per row (the paper layout) and (rows, k) for the
    multi-component entities of the fleet layout (e.g. ``vehicles/1/error/kalman``) with
    k > 1; :func:`read_rrd_series` always returns (rows, k).  Static data (series styles,
    recording properties) is skipped.  Raises ValueError if an entity's rows hold different
    numbers of scalars.
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
        values = _scalar_rows(batch.column(_SCALARS_COLUMN), f"{path}: {entity!r}")
        parts.setdefault(entity, []).append(
            (_int64_index(batch.column(_STEP)), _int64_index(batch.column(_SIM_TIME)), values))

    out: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    for entity, pieces in parts.items():
        step, sim_time, values = _merge_rows(pieces, f"{path}: {entity!r}")
        out[entity] = (step, sim_time, values[:, 0] if values.shape[1] == 1 else values)
    return out


def read_rrd_series(path: str | Path, entity: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read the scalar series of one entity (e.g. ``vehicles/2/state/kalman/true``).

    Returns (step as int64, sim_time as int64 nanoseconds, values as float64 of shape
    (rows, k)), sorted by step; column c is component c (the c-th series line).  Raises
    KeyError if the entity has no scalars and ValueError if rows hold different numbers.
    """
    step, sim_time, cols = _entity_rows(path, entity, _SCALARS_COLUMN)
    values = [_scalar_rows(col, f"{path}: {entity!r}") for col in cols]
    offsets = np.cumsum([0] + [len(v) for v in values])
    return _merge_rows([(step[a:b], sim_time[a:b], v) for a, b, v in zip(offsets[:-1], offsets[1:], values)],
                       f"{path}: {entity!r}")


def _entity_rows(path: str | Path, entity: str, column: str) -> tuple[np.ndarray, np.ndarray, list[pa.Array]]:
    """Temporal rows of one component column of one entity: (step, sim_time, column pieces), unsorted."""
    want = "/" + entity.strip("/")
    steps: list[np.ndarray] = []
    times: list[np.ndarray] = []
    pieces: list[pa.Array] = []
    for chunk in RrdReader(path).stream():
        if chunk.is_static or "/" + chunk.entity_path.strip("/") != want:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if column not in names:
            continue
        if _STEP not in names or _SIM_TIME not in names:
            raise ValueError(f"{path}: {column} chunk of {entity!r} lacks the step/sim_time timelines")
        steps.append(_int64_index(batch.column(_STEP)))
        times.append(_int64_index(batch.column(_SIM_TIME)))
        pieces.append(batch.column(column))
    if not pieces:
        raise KeyError(f"{path}: no temporal {column} data for entity {entity!r}")
    return np.concatenate(steps), np.concatenate(times), pieces


def _uniform(lengths: np.ndarray, what: str) -> int:
    if lengths.size == 0:
        return 0
    if not np.all(lengths == lengths[0]):
        raise ValueError(f"{what}: rows differ in length ({int(lengths.min())}..{int(lengths.max())})")
    return int(lengths[0])


def _lengths(arr: pa.Array) -> np.ndarray:
    return np.asarray(arr.value_lengths().fill_null(0).to_numpy(zero_copy_only=False), dtype=np.int64)


def read_rrd_points(path: str | Path, entity: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read the temporal ``Points3D`` positions of one entity (e.g. ``world/kalman/vehicles``).

    Returns (step as int64, sim_time as int64 nanoseconds, positions as float32 of shape
    (rows, n, 3)), sorted by step.  Raises KeyError if the entity has no positions and
    ValueError if rows hold different numbers of points.
    """
    step, sim_time, pieces = _entity_rows(path, entity, "Points3D:positions")
    rows = []
    for col in pieces:
        n = _uniform(_lengths(col), f"{path}: {entity!r} points")
        xyz = np.asarray(col.flatten().flatten().to_numpy(zero_copy_only=False), dtype=np.float32)
        rows.append(xyz.reshape(len(col), n, 3))
    _uniform(np.asarray([r.shape[1] for r in rows]), f"{path}: {entity!r} points")
    positions = np.concatenate(rows)
    order = np.argsort(step, kind="stable")
    return step[order], sim_time[order], positions[order]


def read_rrd_line_strips(path: str | Path, entity: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read the temporal ``LineStrips3D`` strips of one entity (e.g. ``world/kalman/edges``).

    Returns (step as int64, sim_time as int64 nanoseconds, strips as float32 of shape
    (rows, strips per row, points per strip, 3)), sorted by step.  Raises KeyError if the
    entity has no strips and ValueError if the rows are ragged.
    """
    step, sim_time, pieces = _entity_rows(path, entity, "LineStrips3D:strips")
    rows = []
    for col in pieces:
        n_strips = _uniform(_lengths(col), f"{path}: {entity!r} strips per row")
        inner = col.flatten()
        n_points = _uniform(_lengths(inner), f"{path}: {entity!r} points per strip")
        xyz = np.asarray(inner.flatten().flatten().to_numpy(zero_copy_only=False), dtype=np.float32)
        rows.append(xyz.reshape(len(col), n_strips, n_points, 3))
    _uniform(np.asarray([r.shape[1] * 1000003 + r.shape[2] for r in rows]), f"{path}: {entity!r} strips")
    strips = np.concatenate(rows)
    order = np.argsort(step, kind="stable")
    return step[order], sim_time[order], strips[order]


def _unpack_rgba(packed: int) -> tuple[int, int, int, int]:
    packed = int(packed)  # 0xRRGGBBAA
    return ((packed >> 24) & 0xFF, (packed >> 16) & 0xFF, (packed >> 8) & 0xFF, packed & 0xFF)


def read_rrd_series_lines(path: str | Path) -> dict[str, tuple[tuple[str, ...], tuple[tuple[int, int, int, int], ...]]]:
    """Static series styles of a .rrd, every line: entity path -> (series names, RGBA colours
    0-255), one name and colour per component (one of each in the paper layout)."""
    out: dict[str, tuple[tuple[str, ...], tuple[tuple[int, int, int, int], ...]]] = {}
    for chunk in RrdReader(path).stream():
        if not chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if "SeriesLines:names" not in names or "SeriesLines:colors" not in names:
            continue
        entity = chunk.entity_path.lstrip("/")
        out[entity] = (tuple(batch.column("SeriesLines:names").to_pylist()[-1]),
                       tuple(_unpack_rgba(c) for c in batch.column("SeriesLines:colors").to_pylist()[-1]))
    return out


def read_rrd_series_styles(path: str | Path) -> dict[str, tuple[str, tuple[int, int, int, int]]]:
    """Static series styles of a .rrd: entity path -> (series name, RGBA colour 0-255) of the
    first line of each entity (see :func:`read_rrd_series_lines` for every line)."""
    return {entity: (names[0], colors[0]) for entity, (names, colors) in read_rrd_series_lines(path).items()}


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


_CONTAINER_KINDS = {1: "Tabs", 2: "Horizontal", 3: "Vertical", 4: "Grid"}


def _blueprint_rows(path: str | Path) -> dict[str, dict[str, object]]:
    """Blueprint store of a .rrd: entity path (leading slash) -> component -> last value."""
    reader = RrdReader(path)
    out: dict[str, dict[str, object]] = {}
    for store in reader.blueprints():
        for chunk in reader.stream(store=store):
            batch = chunk.to_record_batch()
            entity = "/" + chunk.entity_path.strip("/")
            for name in batch.schema.names:
                if ":" not in name or batch.num_rows == 0:
                    continue
                value = batch.column(name)[batch.num_rows - 1]
                if value.is_valid:
                    out.setdefault(entity, {})[name] = value
    return out


def read_rrd_blueprint_tree(path: str | Path) -> dict | None:
    """The layout of the blueprint embedded in a .rrd, as nested dicts (None if there is none).

    A container is ``{"kind": "Horizontal" | "Vertical" | "Grid" | "Tabs", "name": str | None,
    "contents": [...]}``; a view is ``{"kind": "view", "class": "3D" | "TimeSeries" | ...,
    "name": str, "origin": str}``.  The root is the viewport's root container.
    """
    rows = _blueprint_rows(path)
    viewport = rows.get("/viewport", {}).get("ViewportBlueprint:root_container")
    if viewport is None:
        return None

    def first(value: object) -> object:
        items = value.as_py() if hasattr(value, "as_py") else value
        return items[0] if isinstance(items, list) and items else None

    def node(entity: str) -> dict:
        comps = rows.get(entity, {})
        if "ViewBlueprint:class_identifier" in comps:
            return {"kind": "view", "class": first(comps["ViewBlueprint:class_identifier"]),
                    "name": first(comps["ViewBlueprint:display_name"]) if "ViewBlueprint:display_name" in comps
                    else None,
                    "origin": first(comps["ViewBlueprint:space_origin"]) if "ViewBlueprint:space_origin" in comps
                    else "/"}
        kind = first(comps.get("ContainerBlueprint:container_kind", pa.scalar([0])))
        name = comps.get("ContainerBlueprint:display_name")
        contents = comps.get("ContainerBlueprint:contents")
        return {"kind": _CONTAINER_KINDS.get(kind, str(kind)),
                "name": first(name) if name is not None else None,
                "contents": [node("/" + c.strip("/")) for c in (contents.as_py() if contents is not None else [])]}

    root = first(viewport)
    root_bytes = bytes(root) if isinstance(root, (bytes, list)) else None
    if root_bytes is None or len(root_bytes) != 16:
        return None
    return node(f"/container/{uuid.UUID(bytes=root_bytes)}")


def _union_value(arr: pa.UnionArray, i: int) -> tuple[str, int | None]:
    """Element i of a dense union as (variant name in snake_case, value or None)."""
    code = arr.type_codes[i].as_py()
    child = list(arr.type.type_codes).index(code)
    name = arr.type.field(child).name
    snake = "".join(("_" + ch.lower()) if ch.isupper() else ch for ch in name).lstrip("_")
    field = arr.field(child)
    value = None if pa.types.is_null(field.type) else field[arr.offsets[i].as_py()].as_py()
    return snake, value


def read_rrd_visible_time_ranges(
        path: str | Path) -> dict[tuple[str, str | None], dict[str, tuple[tuple[str, int | None], tuple[str, int | None]]]]:
    """Visible time ranges set in the embedded blueprint.

    Returns (view name, entity path with leading slash, or None for the view-wide setting)
    -> timeline -> ((start kind, start value), (end kind, end value)); kinds are
    ``cursor_relative``, ``absolute`` or ``infinite`` (value None); values are integer
    nanoseconds on duration timelines and sequence numbers on sequence timelines.
    """
    rows = _blueprint_rows(path)
    names = {e: comps["ViewBlueprint:display_name"].as_py()[0]
             for e, comps in rows.items() if "ViewBlueprint:display_name" in comps}
    out: dict[tuple[str, str | None], dict[str, tuple[tuple[str, int | None], tuple[str, int | None]]]] = {}
    for entity, comps in rows.items():
        value = comps.get("VisibleTimeRanges:ranges")
        if value is None or not entity.startswith("/view/"):
            continue
        parts = entity.split("/")  # ['', 'view', uuid, ...]
        view_entity = "/".join(parts[:3])
        rest = parts[3:]
        if rest[:2] == ["ViewContents", "overrides"] and rest[-1:] == ["visualizers"]:
            target: str | None = "/" + "/".join(rest[2:-1])
        elif rest == ["VisibleTimeRanges"]:
            target = None
        else:
            continue
        ranges = value.values  # StructArray of {timeline, range: {start, end}}
        timelines = ranges.field("timeline")
        starts = ranges.field("range").field("start")
        ends = ranges.field("range").field("end")
        per_timeline = {}
        for i in range(len(ranges)):
            per_timeline[timelines[i].as_py()] = (_union_value(starts, i), _union_value(ends, i))
        out[(names.get(view_entity, view_entity), target)] = per_timeline
    return out


def rrd_has_blueprint(path: str | Path) -> bool:
    """True if the .rrd embeds a blueprint store with at least one view."""
    return bool(read_rrd_blueprint_views(path))
