"""The default Rerun blueprints embedded in a .rrd: the grid of paper-figure views, and the
fleet layout (3D view(s) on the left, per-vehicle error/control views on the right)."""
from __future__ import annotations

import numpy as np
import rerun.blueprint as rrb

from .layout import _SIM_TIME, _STEP, VIEW_GROUPS


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
        rrb.VisibleTimeRange(_SIM_TIME,
                             start=rrb.TimeRangeBoundary.cursor_relative(nanos=-trail_ns),
                             end=rrb.TimeRangeBoundary.cursor_relative()),
        rrb.VisibleTimeRange(_STEP, start=rrb.TimeRangeBoundary.cursor_relative(seq=-trail_steps),
                             end=rrb.TimeRangeBoundary.cursor_relative()),
    ])


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
            contents=[v for i in range(1, n + 1) for v in vehicle_views(i)], grid_columns=2,
            name="vehicles")
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
