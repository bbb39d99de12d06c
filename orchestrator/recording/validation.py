"""Checks of what :func:`~orchestrator.recording.write_rrd` is given (runs, step, fleet
layout, strides and durations); each raises ValueError naming the argument or field at
fault."""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .layout import _POSITION_NAMES, TRACE_KEYS, FleetLayout, _Fleet


def _index_array(value: object, field: str, cols: int | None) -> np.ndarray:
    """A 2-D integer array (N, cols) from a FleetLayout field, or ValueError naming it."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "iu":
        raise ValueError(f"write_rrd: fleet.{field} must be an integer array, "
                         f"got dtype {arr.dtype}")
    if arr.ndim != 2 or (cols is not None and arr.shape[1] != cols) or arr.shape[1] < 1:
        want = f"(N, {cols})" if cols is not None else "(N, k) with k >= 1"
        raise ValueError(f"write_rrd: fleet.{field} must have shape {want}, got shape {arr.shape}")
    return arr.astype(np.int64)


def _check_columns(arr: np.ndarray, field: str, clean: dict[str, dict[str, np.ndarray]],
                   key: str) -> None:
    """Every entry of an index array must be a column of trace ``key`` in every run."""
    for method, traces in clean.items():
        dim = traces[key].shape[1]
        bad = np.argwhere((arr < 0) | (arr >= dim))
        if bad.size:
            r, c = (int(v) for v in bad[0])
            raise ValueError(f"write_rrd: fleet.{field}[{r}, {c}] = {int(arr[r, c])} "
                             f"(vehicle {r + 1}) is out of range for run {method!r} trace "
                             f"{key!r}, which has {dim} columns (valid 0..{dim - 1})")


def _check_names(names: object, field: str, count: int, index_field: str) -> tuple[str, ...]:
    """Component labels: ``count`` distinct, non-empty entity path parts."""
    if isinstance(names, str) or not isinstance(names, (tuple, list)):
        raise ValueError(f"write_rrd: fleet.{field} must be a tuple of strings, got {names!r}")
    names = tuple(names)
    if len(names) != count:
        raise ValueError(f"write_rrd: fleet.{field} has {len(names)} labels, but "
                         f"fleet.{index_field} has {count} columns per vehicle")
    for n in names:
        if not isinstance(n, str) or not n or "/" in n or n.strip() != n:
            raise ValueError(f"write_rrd: fleet.{field} label {n!r} is not a valid entity path "
                             "part (non-empty string, no '/', no surrounding spaces)")
    if len(set(names)) != len(names):
        raise ValueError(f"write_rrd: fleet.{field} labels must be distinct, got {names!r}")
    return names


def _vehicle_number(v: object, n: int, where: str) -> int:
    """A 1-based vehicle number in 1..n, returned 0-based, or ValueError naming ``where``."""
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
        raise ValueError(f"write_rrd: {where} = {v!r} is not an integer vehicle number")
    if not 1 <= int(v) <= n:
        raise ValueError(f"write_rrd: {where} names vehicle {int(v)}, which does not exist: "
                         f"the fleet has N = {n} vehicles, numbered 1..{n}")
    return int(v) - 1


def _validate_fleet(fleet: FleetLayout, clean: dict[str, dict[str, np.ndarray]]) -> _Fleet:
    """Check a FleetLayout against the (validated) traces of every run."""
    if not isinstance(fleet, FleetLayout):
        raise ValueError(f"write_rrd: fleet must be a FleetLayout, got {type(fleet).__name__}")
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
            raise ValueError(f"write_rrd: fleet.{field} has {arr.shape[0]} rows, but "
                             f"fleet.position_index has {n} (one row per vehicle)")
    _check_columns(pos, "position_index", clean, "x")
    _check_columns(err, "error_index", clean, "e")
    _check_columns(ctl, "control_index", clean, "u")
    if fleet.state_index is not None:
        _check_columns(sta, "state_index", clean, "x")
    _check_columns(sta, "state_index" if fleet.state_index is not None else "position_index",
                   clean, "xhat")
    error_names = _check_names(fleet.error_names, "error_names", err.shape[1], "error_index")
    control_names = _check_names(fleet.control_names, "control_names", ctl.shape[1],
                                 "control_index")
    if fleet.state_index is None and fleet.state_names is None:
        state_names: tuple[str, ...] = _POSITION_NAMES
    else:
        state_names = _check_names(fleet.state_names, "state_names", sta.shape[1],
                                   "state_index" if fleet.state_index is not None
                                   else "position_index")
    disturbance_names: tuple[str, ...] = ()
    if dis is not None:
        _check_columns(dis, "disturbance_index", clean, "w")
        _check_columns(dis, "disturbance_index", clean, "what")
        disturbance_names = _check_names(fleet.disturbance_names, "disturbance_names", dis.shape[1],
                                         "disturbance_index")
    elif fleet.disturbance_names is not None:
        raise ValueError("write_rrd: fleet.disturbance_names is given without "
                         "fleet.disturbance_index")

    try:
        lead = np.asarray(fleet.leader_output, dtype=np.float64)
        offsets = np.asarray(fleet.offsets, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"write_rrd: fleet.leader_output / fleet.offsets must be float "
                         f"arrays: {exc}") from exc
    for method, traces in clean.items():
        l_dim = traces["z"].shape[1]
        if lead.shape != (3, l_dim):
            raise ValueError(f"write_rrd: fleet.leader_output must have shape (3, l) = "
                             f"(3, {l_dim}) to map run {method!r} trace 'z' ({l_dim} columns) "
                             f"to a position, got shape {lead.shape}")
    if not np.all(np.isfinite(lead)):
        raise ValueError("write_rrd: fleet.leader_output has non-finite entries")
    if offsets.shape != (n, 3):
        raise ValueError(f"write_rrd: fleet.offsets must have shape (N, 3) = ({n}, 3), "
                         f"got shape {offsets.shape}")
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
        error_unit=fleet.error_unit, control_unit=fleet.control_unit,
        n_max=_optional_positive(fleet.n_max, "fleet.n_max"),
        delta_max=_optional_positive(fleet.delta_max, "fleet.delta_max"),
    )


def _optional_positive(value: float | None, what: str) -> float | None:
    """None, or ``value`` as a positive finite float (ValueError naming ``what``)."""
    if value is None:
        return None
    v = float(value)
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"write_rrd: {what} = {value!r} must be a positive number")
    return v


def _validate(runs: Mapping[str, Mapping[str, np.ndarray]], h: float,
              keys: tuple[str, ...] = TRACE_KEYS
              ) -> tuple[dict[str, dict[str, np.ndarray]], int, int]:
    """Check the runs and the step; return float64 traces (``keys``: those the layout
    places), the step count and h in ns."""
    if not isinstance(runs, Mapping) or len(runs) == 0:
        raise ValueError("write_rrd: runs must be a non-empty mapping method -> traces")
    h_ns = _step_ns(h)

    clean: dict[str, dict[str, np.ndarray]] = {}
    steps: int | None = None
    first: tuple[str, str] | None = None
    for method, traces in runs.items():
        _method_name(method)
        if not isinstance(traces, Mapping):
            raise ValueError(f"write_rrd: run {method!r} must be a mapping of traces, "
                             f"got {type(traces).__name__}")
        missing = [k for k in keys if k not in traces]
        if missing:
            raise ValueError(f"write_rrd: run {method!r} is missing trace key(s) "
                             f"{', '.join(repr(k) for k in missing)} "
                             f"(needs {', '.join(keys)})")
        clean[method] = {}
        for key in keys:
            try:
                arr = np.asarray(traces[key], dtype=np.float64)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"write_rrd: run {method!r} trace {key!r} is not a float "
                                 f"array: {exc}") from exc
            if arr.ndim != 2:
                raise ValueError(f"write_rrd: run {method!r} trace {key!r} must have shape "
                                 f"(steps, dim), got shape {arr.shape}")
            if steps is None:
                steps, first = arr.shape[0], (method, key)
            elif arr.shape[0] != steps:
                raise ValueError(f"write_rrd: run {method!r} trace {key!r} has "
                                 f"{arr.shape[0]} steps, but run {first[0]!r} trace "
                                 f"{first[1]!r} has {steps}; "
                                 "all runs and traces must have the same number of steps")
            clean[method][key] = arr
    assert steps is not None
    if steps == 0:
        raise ValueError("write_rrd: traces have zero steps; nothing to write")
    return clean, steps, h_ns


def _step_ns(h: object) -> int:
    """The step h (s, > 0, at least 1 ns) as integer nanoseconds, or ValueError."""
    h = float(h)  # type: ignore[arg-type]
    if not np.isfinite(h) or h <= 0.0:
        raise ValueError(f"write_rrd: step h must be a positive number of seconds, got {h!r}")
    h_ns = round(h * 1e9)
    if h_ns < 1:
        raise ValueError(f"write_rrd: step h={h!r} s is below one nanosecond")
    return h_ns


def _method_name(method: object) -> str:
    """A method name usable as an entity path part, or ValueError."""
    if not isinstance(method, str) or not method or "/" in method or method.strip() != method:
        raise ValueError(f"write_rrd: method name {method!r} is not a valid entity path part "
                         "(non-empty, no '/', no surrounding spaces)")
    return method


def _positive_ns(value: object, name: str) -> int:
    """A positive finite duration in seconds as integer nanoseconds (>= 1), or ValueError."""
    try:
        seconds = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        seconds = float("nan")
    if isinstance(value, (bool, np.bool_)) or not np.isfinite(seconds) or seconds <= 0.0:
        raise ValueError(f"write_rrd: {name} must be a positive number of seconds, got {value!r}")
    return max(1, round(seconds * 1e9))


def _positive_int(value: object, name: str) -> int:
    """A positive integer (Python or numpy int, not bool), or ValueError naming ``name``."""
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer))
            or int(value) < 1):
        raise ValueError(f"write_rrd: {name} must be a positive integer number of steps, "
                         f"got {value!r}")
    return int(value)
