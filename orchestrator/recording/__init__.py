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

Modules
-------
* :mod:`.layout`: trace keys, entity paths and series names, :class:`FleetLayout`, colours;
* :mod:`.validation`: the checks of the arguments of :func:`write_rrd`;
* :mod:`.blueprint`: the default blueprints (paper grid, fleet layout);
* :mod:`.writer`: :func:`write_rrd` and its ``send_columns`` writers;
* :mod:`.reader`: read the recorded data back without a viewer (``read_rrd_*``).
"""
from __future__ import annotations

from .layout import TRACE_KEYS, VIEW_GROUPS, FleetLayout, method_color
from .reader import (
    read_rrd_line_strips,
    read_rrd_points,
    read_rrd_scalars,
    read_rrd_series,
    read_rrd_series_lines,
)
from .writer import write_rrd

__all__ = [
    "TRACE_KEYS",
    "VIEW_GROUPS",
    "FleetLayout",
    "method_color",
    "read_rrd_line_strips",
    "read_rrd_points",
    "read_rrd_scalars",
    "read_rrd_series",
    "read_rrd_series_lines",
    "write_rrd",
]
