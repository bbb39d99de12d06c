"""The default Rerun blueprints embedded in a .rrd.

Paper layout (tabs):

- "paper figures 2-7": one row per figure pair, error-1/2, state-1/2, control-1/2 (the
  paper's figures), the methods overlaid;
- "disturbance & reference": the disturbance and reference components;
- "estimates, full scale": the state, disturbance and reference views with automatic axes.

Every time-series view shows the whole run (both timelines unbounded), with its legend
hidden: a one-line legend view on top names the colours instead, so no legend covers data.
Every view's name carries its unit (the paper example is dimensionless) and its y-axis
covers its data with at least three labelled ticks (:mod:`.ranges`).
The state, disturbance and reference views of the first two tabs draw the true signals (each
method's state, which its own control drives; the disturbance and reference once, as every
method sees the same) with each method's estimate, and scale the y-axis to the true
signals (a margin of 15 % of their span), so a method whose estimate spikes
(the classical law) does not squash the others: an estimate with more than 1 % of its
samples outside that range is left out there (the view's name says so) and shown in the
third tab with the others at full scale. The time panel starts paused and folded.

Fleet layout: the 3D view(s) on the left, framed from above and behind the formation to hold
every vehicle and the leader over the whole run; below them the actuators (nonlinear
vehicles: one view per actuator kind) and the links (acoustic links: their legend line and
counts); per-vehicle error/control (and age of information) views on the right (a grid, or
tabs of grids for many vehicles), whole run, legends hidden; every error view on one y
range and every control view on one (:func:`fleet_ranges`), so they compare at a glance.
"""
from __future__ import annotations

import numpy as np
import rerun.blueprint as rrb
from rerun.encodings import TimeRange

from .layout import _SIM_TIME, _STEP, VIEW_GROUPS, _Fleet
from .ranges import DIMENSIONLESS, data_range, tick_range, unit_of
from .selection import Selection

#: entity of the one-line colour legend (a markdown TextDocument written by the writer)
LEGEND_ENTITY = "legend"
#: groups whose views overlay a true signal and estimates (the y-axis fits the true signal)
_TRUE_GROUPS = {"state": ("x", "xhat"), "disturbance": ("w", "what"),
                "reference": ("z", "zhat")}
_MARGIN = 0.15


def _whole_run() -> list[rrb.VisibleTimeRange]:
    """Visible range: the whole recording, on both timelines."""
    return [rrb.VisibleTimeRange(t, start=rrb.TimeRangeBoundary.infinite(),
                                 end=rrb.TimeRangeBoundary.infinite())
            for t in (_SIM_TIME, _STEP)]


def _series_view(name: str, origin: str, contents: list[str] | None = None,
                 y_range: tuple[float, float] | None = None) -> rrb.TimeSeriesView:
    return rrb.TimeSeriesView(
        name=name, origin=origin, contents=contents or "$origin/**",
        plot_legend=rrb.PlotLegend(visible=False), time_ranges=_whole_run(),
        axis_x=rrb.TimeAxis(view_range=TimeRange(start=rrb.TimeRangeBoundary.infinite(),
                                                 end=rrb.TimeRangeBoundary.infinite())),
        axis_y=None if y_range is None else rrb.ScalarAxis(range=y_range, zoom_lock=False))


def _auto_view(name: str, origin: str, contents: list[str] | None = None,
               y_range: tuple[float, float] | None = None) -> rrb.TimeSeriesView:
    """:func:`_series_view` with an automatic y-axis (``y_range`` ignored): a live viewer's
    views, whose data are still to come."""
    return _series_view(name, origin, contents)


def true_signal_range(true: np.ndarray) -> tuple[float, float]:
    """The y-axis of a view comparing estimates with ``true``: its range widened by 15 % of
    its span on each side, then to hold three labelled ticks (:func:`.ranges.tick_range`).

    Parameters
    ----------
    true : np.ndarray
        The true signal (one component over the run).

    Returns
    -------
    tuple[float, float]
        (low, high).
    """
    return tick_range(float(np.min(true)), float(np.max(true)), _MARGIN)


def _true_and_estimates(group: str, i: int, methods: list[str],
                        clean: dict[str, dict[str, np.ndarray]], fixed: bool = True
                        ) -> tuple[rrb.TimeSeriesView, rrb.TimeSeriesView]:
    """(fitted view, full-scale view) of component i of a true-vs-estimate group: the fitted
    view's y-axis fits the true signals and holds the estimates that stay (99 % of samples)
    within it; the others are left to the full-scale view, and the name says so. Not
    ``fixed`` (a live viewer): every estimate in both, automatic y-axes."""
    true_key, est_key = _TRUE_GROUPS[group]
    # the state depends on each method's control: every method's; w and z are shared: once
    owners = methods if group == "state" else methods[:1]
    owners = [m for m in owners if clean[m][true_key].shape[1] >= i]
    if not fixed:
        every = [f"+ /{group}/{i}/{m}/true" for m in owners] + [
            f"+ /{group}/{i}/{m}/estimate" for m in methods if clean[m][est_key].shape[1] >= i]
        return (_series_view(f"{group}-{i} ({DIMENSIONLESS})", f"/{group}/{i}", every),
                _series_view(f"{group}-{i} full scale ({DIMENSIONLESS})", f"/{group}/{i}",
                             every))
    lo, hi = true_signal_range(np.concatenate([clean[m][true_key][:, i - 1] for m in owners]))
    shown, left_out = [], []
    for m in methods:
        est = clean[m][est_key]
        if est.shape[1] < i:
            continue
        outside = np.mean((est[:, i - 1] < lo) | (est[:, i - 1] > hi))
        (shown if outside <= 0.01 else left_out).append(m)
    trues = [f"+ /{group}/{i}/{m}/true" for m in owners]
    name = f"{group}-{i} ({DIMENSIONLESS})" + (
        f" · {', '.join(left_out)} estimate: see full scale" if left_out else "")
    fitted = _series_view(name, f"/{group}/{i}", trues + [
        f"+ /{group}/{i}/{m}/estimate" for m in shown], (lo, hi))
    every = [clean[m][true_key][:, i - 1] for m in owners] + [
        clean[m][est_key][:, i - 1] for m in shown + left_out]
    full = _series_view(f"{group}-{i} full scale ({DIMENSIONLESS})", f"/{group}/{i}",
                        trues + [f"+ /{group}/{i}/{m}/estimate" for m in shown + left_out],
                        data_range(every))
    return fitted, full


def _blueprint(clean: dict[str, dict[str, np.ndarray]], fixed: bool = True,
               selection: Selection | None = None) -> rrb.Blueprint:
    """The paper layout (module docstring) for the runs ``clean`` (method -> traces); not
    ``fixed``: the layout of a live viewer, every y-axis automatic (the data are to come).
    ``selection``: the recorded groups (default all), whose views only are laid out."""
    methods = list(clean)
    selection = selection or Selection(fleet=False)
    view = _series_view if fixed else _auto_view
    rows: dict[str, list[rrb.TimeSeriesView]] = {}
    full: list[rrb.Horizontal] = []
    for group, keys in VIEW_GROUPS:
        if not selection.has(group):
            continue
        dim = max(run[k].shape[1] for run in clean.values() for k in keys)
        if group in _TRUE_GROUPS:
            pairs = [_true_and_estimates(group, i, methods, clean, fixed)
                     for i in range(1, dim + 1)]
            rows[group] = [p[0] for p in pairs]
            full.append(rrb.Horizontal(*[p[1] for p in pairs], name=f"{group}, full scale"))
        else:
            rows[group] = [view(
                f"{group}-{i} ({DIMENSIONLESS})", f"/{group}/{i}", None,
                data_range([run[k][:, i - 1] for run in clean.values() for k in keys
                            if run[k].shape[1] >= i]))
                for i in range(1, dim + 1)]
    tabs = [rrb.Vertical(*[rrb.Horizontal(*rows[g], name=g) for g in groups if g in rows],
                         name=name)
            for name, groups in (("paper figures 2-7", ("error", "state", "control")),
                                 ("disturbance & reference", ("disturbance", "reference")))
            if any(g in rows for g in groups)]
    if full:
        tabs.append(rrb.Vertical(*full, name="estimates, full scale"))
    if selection.groups is not None and "measurement" in selection.groups:  # asked for
        tabs.append(_auto_view("measurements", "/measurement"))
    legend = rrb.TextDocumentView(origin=f"/{LEGEND_ENTITY}", name="legend")
    return rrb.Blueprint(
        rrb.Vertical(legend, rrb.Tabs(*tabs, active_tab=0), row_shares=[1.0, 14.0],
                     name="auv-cosim"),
        *_panels(fixed),
    )


def _panels(fixed: bool = True) -> tuple:
    """Side panels folded away (more room for the plots), the time panel paused (not
    ``fixed``, a live viewer: following the newest data)."""
    return (rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
            rrb.TimePanel(timeline=_SIM_TIME, play_state="paused" if fixed else "following",
                          state="collapsed"))


#: Vehicles per tab of the right-hand side of the fleet blueprint when N > _FLEET_GRID_MAX.
_FLEET_TAB_SIZE = 4
_FLEET_GRID_MAX = 8


def _trail_time_ranges(trail_ns: int, trail_steps: int) -> rrb.VisibleTimeRanges:
    """Visible range [cursor - trail, cursor] on both timelines."""
    return rrb.VisibleTimeRanges([
        rrb.VisibleTimeRange(_SIM_TIME,
                             start=rrb.TimeRangeBoundary.cursor_relative(nanos=-trail_ns),
                             end=rrb.TimeRangeBoundary.cursor_relative()),
        rrb.VisibleTimeRange(_STEP, start=rrb.TimeRangeBoundary.cursor_relative(seq=-trail_steps),
                             end=rrb.TimeRangeBoundary.cursor_relative()),
    ])


#: eye distance / the bounding box's half-diagonal: 1 / sin(30 deg)
_EYE_DISTANCE = 1.0 / float(np.sin(np.radians(30.0)))


def fleet_camera(points: np.ndarray) -> rrb.EyeControls3D:
    """A camera that holds every point of ``points`` (NED, m; any shape (..., 3)): an orbit
    around the centre of their bounding box, from above and a little behind (south), at
    twice the box's half-diagonal (at least 5 m): the sphere round the box fits in a 60
    degree field of view, so every trail of the run stays in frame.

    Parameters
    ----------
    points : np.ndarray
        Every position the view must show (vehicles and leader over the whole run).

    Returns
    -------
    rrb.EyeControls3D
        Orbital eye: position, look target and up (-down) in the view's NED frame.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 5.0)
    direction = np.array([-0.45, -0.12, -0.88])            # south, west, mostly up (NED)
    eye = centre + _EYE_DISTANCE * radius * direction / np.linalg.norm(direction)
    return rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, position=eye.tolist(),
                             look_target=centre.tolist(), eye_up=[0.0, 0.0, -1.0])


def fleet_ranges(fleet: _Fleet, runs: dict[str, dict[str, np.ndarray]]
                 ) -> tuple[tuple[float, float] | None, tuple[float, float] | None]:
    """The y ranges of the fleet's error views and of its control views: each one range
    for every vehicle and every method (the views of a comparison share their scale, so
    the gap between the methods and between the vehicles shows).

    Parameters
    ----------
    fleet : _Fleet
    runs : dict[str, dict[str, np.ndarray]]
        Method -> traces.

    Returns
    -------
    tuple
        (error range, control range); None for one not recorded.
    """
    def of(key: str, index: np.ndarray) -> tuple[float, float] | None:
        if not all(key in r for r in runs.values()):      # not recorded
            return None
        return data_range([r[key][:, index.ravel()] for r in runs.values()])
    return of("e", fleet.error_index), of("u", fleet.control_index)


def _fleet_blueprint(methods: list[str], fleet: _Fleet, trail_ns: int, trail_steps: int,
                     runs: dict[str, dict[str, np.ndarray]],
                     links: dict[str, list[str]] | None = None,
                     points: np.ndarray | None = None, fixed: bool = True,
                     selection: Selection | None = None) -> rrb.Blueprint:
    """3D view(s) of the fleet on the left (framed by :func:`fleet_camera` on every vehicle
    and leader position), under them the actuator views (nonlinear vehicles) and the links
    (legend line and counts); per-vehicle error/control (and age of information) views on
    the right (whole run, legends hidden: the legend view on top names the colours).
    ``points``: every vehicle and leader position to frame, if not those of ``runs``. Not
    ``fixed`` (a live viewer, the data to come): automatic y-axes and camera. ``selection``:
    the recorded groups (default all), whose views only are laid out."""
    n = fleet.n
    selection = selection or Selection(fleet=True)
    view = _series_view if fixed else _auto_view
    if not selection.has("scene"):
        points = np.zeros((1, 3))       # no 3D view to frame
    if points is None:                  # else: the extremes, kept as a stream went
        points = np.concatenate(
            [np.concatenate([run["x"][:, fleet.position_index].reshape(-1, 3),
                             run["z"] @ fleet.leader_output.T]) for run in runs.values()])
    camera = fleet_camera(points) if fixed else None
    views_3d = [
        rrb.Spatial3DView(
            name=f"fleet {m}",
            origin=f"/world/{m}",
            eye_controls=camera,
            overrides={f"/world/{m}/trails": _trail_time_ranges(trail_ns, trail_steps)},
        )
        for m in methods
    ]
    left_parts: list[rrb.Container | rrb.View] = []
    shares: list[float] = []
    if selection.has("scene"):
        left_parts.append(views_3d[0] if len(views_3d) == 1
                          else rrb.Tabs(*views_3d, active_tab=0, name="fleet 3D"))
        shares.append(3.0)
    # the nonlinear vehicle: actuators per kind
    if selection.has("actuators") and any("rpm" in r for r in runs.values()):
        from .actuators import DEFAULT_DELTA_MAX, DEFAULT_N_MAX, actuator_views
        left_parts.append(actuator_views(
            n, runs, fleet.n_max or DEFAULT_N_MAX, fleet.delta_max or DEFAULT_DELTA_MAX, view))
        shares.append(2.2)
    ages: dict[int, rrb.TimeSeriesView] = {}
    if links and selection.has("links"):    # acoustic links: counts under the 3D view
        from .network import network_view
        links_part, age_views = network_view(runs, links, view)
        ages = {int(i): v for i, v in age_views.items() if i.isdigit()}
        left_parts.append(links_part)
        shares.append(1.6)
    left = (None if not left_parts else left_parts[0] if len(left_parts) == 1
            else rrb.Vertical(*left_parts, row_shares=shares))
    error_unit = unit_of(fleet.error_names, fleet.error_unit)
    control_unit = unit_of(fleet.control_names, fleet.control_unit)

    # one y range for every vehicle's errors, one for their controls (a live viewer: auto)
    err, ctl = fleet_ranges(fleet, runs) if fixed else (None, None)

    def vehicle_views(i: int) -> list[rrb.TimeSeriesView]:
        views = []
        if selection.has("error"):
            views.append(view(f"vehicle {i} error ({error_unit})", f"/vehicles/{i}/error",
                              None, err))
        if selection.has("control"):
            views.append(view(f"vehicle {i} control ({control_unit})",
                              f"/vehicles/{i}/control", None, ctl))
        if i in ages:
            views.append(ages[i])
        return views

    columns = max(1, len(vehicle_views(1)))
    if n <= _FLEET_GRID_MAX:
        right: rrb.Container = rrb.Grid(
            contents=[v for i in range(1, n + 1) for v in vehicle_views(i)],
            grid_columns=columns, name="vehicles")
    else:
        tabs = []
        for a in range(1, n + 1, _FLEET_TAB_SIZE):
            b = min(a + _FLEET_TAB_SIZE - 1, n)
            tabs.append(rrb.Grid(contents=[v for i in range(a, b + 1) for v in vehicle_views(i)],
                                 grid_columns=columns, name=f"vehicles {a}-{b}"))
        right = rrb.Tabs(*tabs, active_tab=0, name="vehicles")
    legend = rrb.TextDocumentView(origin=f"/{LEGEND_ENTITY}", name="legend")
    sides = [p for p in (left, right if vehicle_views(1) else None) if p is not None]
    if not sides:                       # only series without views of their own (state, ...)
        sides = [_auto_view("vehicles", "/vehicles")]
    body = sides[0] if len(sides) == 1 else rrb.Horizontal(*sides, column_shares=[1.0, 1.0])
    return rrb.Blueprint(
        rrb.Vertical(legend, body, row_shares=[1.0, 14.0], name="fleet"),
        *_panels(fixed),
    )
