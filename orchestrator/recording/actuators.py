"""The nonlinear vehicle's actuators in the recording (``remus100-6dof`` fleets): every
vehicle's propeller speed, rudder and stern-plane angles and saturation flag, the actuator
limits as constant series, and the blueprint views that group them per actuator kind.

Entities, per method m and vehicle i::

    vehicles/{i}/propeller/{m}   propeller speed, rpm
    vehicles/{i}/fins/{m}        rudder and stern-plane angles, rad (two lines)
    vehicles/{i}/rudder/{m}      rudder angle, rad (for the per-kind view)
    vehicles/{i}/stern/{m}       stern-plane angle, rad (for the per-kind view)
    vehicles/{i}/saturated/{m}   1 while an actuator is at its limit, else 0
    limits/propeller             n_max, rpm (constant)
    limits/fins                  +delta_max and -delta_max, rad (constant)
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from .layout import TRUE_COLOR, _shade
from .ranges import data_range

__all__ = ["ACTUATOR_KINDS", "DEFAULT_DELTA_MAX", "DEFAULT_N_MAX", "actuator_views",
           "send_actuators", "send_limits"]

#: REMUS 100 limits (plant_model.remus100.dynamics): propeller rpm, fin angle rad
DEFAULT_N_MAX = 1525.0
DEFAULT_DELTA_MAX = float(np.radians(15.0))
#: (entity group, trace key, view name, limits entity or None)
ACTUATOR_KINDS: tuple[tuple[str, str, str, str | None], ...] = (
    ("propeller", "rpm", "propeller speed (rpm)", "limits/propeller"),
    ("rudder", "rudder", "rudder (rad)", "limits/fins"),
    ("stern", "stern", "stern planes (rad)", "limits/fins"),
    ("saturated", "saturated", "saturated (0/1)", None),
)
_LIMIT_WIDTH = 2.0


def send_actuators(rec: rr.RecordingStream, method: str, traces: Mapping[str, np.ndarray],
                   n: int, stride: int, indexes: list[Any], method_index: int,
                   vehicle_colors: np.ndarray) -> int:
    """Log one run's actuator series (module docstring), one colour per vehicle (its 3D
    colour, shaded per method); returns the number of scalar lines written.

    Parameters
    ----------
    rec : rr.RecordingStream
        The open recording.
    method : str
        The run's method name.
    traces : Mapping[str, np.ndarray]
        The run's traces: ``rpm``, ``rudder``, ``stern`` (steps, N), ``saturated`` optional.
    n : int
        Vehicles.
    stride : int
        Record every stride-th step.
    indexes : list
        The time columns of the recorded steps.
    method_index : int
        The method's place (shade).
    vehicle_colors : np.ndarray
        (N, 3) uint8, the vehicles' 3D colours.

    Returns
    -------
    int
        Lines written.
    """
    lines = 0

    def send(entity: str, values: np.ndarray, names: list[str],
             colors: list[tuple[int, int, int]]) -> None:
        nonlocal lines
        rec.log(entity, rr.SeriesLines(colors=colors, names=names,
                                       aggregation_policy="MinMax"), static=True)
        rec.send_columns(entity, indexes=indexes, columns=rr.Scalars.columns(
            scalars=np.ascontiguousarray(values, dtype=np.float64)))
        lines += values.shape[1]

    rec_traces = {k: np.asarray(traces[k], float)[::stride]
                  for k in ("rpm", "rudder", "stern", "saturated") if k in traces}
    for i in range(1, n + 1):
        color = _shade(tuple(int(c) for c in vehicle_colors[i - 1]), method_index)
        col = slice(i - 1, i)
        send(f"vehicles/{i}/propeller/{method}", rec_traces["rpm"][:, col],
             [f"{method} rpm"], [color])
        send(f"vehicles/{i}/fins/{method}",
             np.hstack([rec_traces["rudder"][:, col], rec_traces["stern"][:, col]]),
             [f"{method} rudder (rad)", f"{method} stern planes (rad)"], [color, color])
        for kind in ("rudder", "stern", "saturated"):
            if kind in rec_traces:
                send(f"vehicles/{i}/{kind}/{method}", rec_traces[kind][:, col],
                     [f"{method} vehicle {i} {kind}"], [color])
    return lines


def send_limits(rec: rr.RecordingStream, indexes: list[Any], n_max: float,
                delta_max: float) -> None:
    """The limits as constant series (white, wider) on the given time columns (the first and
    last recorded step are enough: the viewer joins them): ``limits/propeller`` (n_max) and
    ``limits/fins`` (+delta_max, -delta_max).

    Parameters
    ----------
    rec : rr.RecordingStream
        The open recording.
    indexes : list
        Time columns of two rows (first and last recorded step).
    n_max : float
        Propeller limit, rpm.
    delta_max : float
        Fin limit, rad.
    """
    for entity, values, names in (
            ("limits/propeller", [n_max], [f"n_max {n_max:g} rpm"]),
            ("limits/fins", [delta_max, -delta_max],
             [f"+delta_max {delta_max:.4g} rad", f"-delta_max {-delta_max:.4g} rad"])):
        rec.log(entity, rr.SeriesLines(colors=[TRUE_COLOR] * len(values), names=names,
                                       widths=[_LIMIT_WIDTH] * len(values),
                                       aggregation_policy="MinMax"), static=True)
        rows = np.tile(np.asarray(values, dtype=np.float64), (2, 1))
        rec.send_columns(entity, indexes=indexes, columns=rr.Scalars.columns(scalars=rows))


def actuator_views(n: int, runs: Mapping[str, Mapping[str, np.ndarray]], n_max: float,
                   delta_max: float,
                   series_view: Callable[..., rrb.TimeSeriesView]) -> rrb.Grid:
    """A 2 x 2 grid of one view per actuator kind (:data:`ACTUATOR_KINDS`), each holding every
    vehicle (and method) and its limits, its y-axis covering both.

    Parameters
    ----------
    n : int
        Vehicles.
    runs : Mapping[str, Mapping[str, np.ndarray]]
        Method -> traces (for the y ranges).
    n_max : float
        Propeller limit, rpm.
    delta_max : float
        Fin limit, rad.
    series_view : Callable
        ``series_view(name, origin, contents, y_range)`` of the blueprint.

    Returns
    -------
    rrb.Grid
        Named "actuators".
    """
    limits = {"rpm": [np.array([0.0, n_max])], "rudder": [np.array([-delta_max, delta_max])],
              "stern": [np.array([-delta_max, delta_max])], "saturated": [np.array([0.0, 1.0])]}
    views = []
    for group, key, name, limit in ACTUATOR_KINDS:
        data = [np.asarray(r[key]) for r in runs.values() if key in r]
        if not data:
            continue
        contents = [f"+ /vehicles/{i}/{group}/**" for i in range(1, n + 1)]
        if limit is not None:
            contents.append(f"+ /{limit}")
        views.append(series_view(name, "/", contents,
                                 data_range(data + limits[key])))
    return rrb.Grid(contents=views, grid_columns=2, name="actuators")
