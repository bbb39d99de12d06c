"""What goes where in a recording: trace keys, entity paths and series names of the paper
layout, the blueprint view groups, the :class:`FleetLayout` of a fleet, method and vehicle colours.

The entity paths themselves are tabulated in docs/recording.md (:mod:`orchestrator.recording`).
"""
from __future__ import annotations

import colorsys
from dataclasses import dataclass

import numpy as np

from estimator_fmu.registry import ESTIMATORS

__all__ = ["FLEET_TRACE_KEYS", "TRACE_KEYS", "TRUE_COLOR", "VIEW_GROUPS", "FleetLayout",
           "MethodStyle", "axis_colors", "color_name", "fleet_method_line", "method_color",
           "method_styles"]

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

#: Trace keys every run must provide (each an array of shape (steps, dim)): the outputs of
#: the loop's system description (orchestrator.cosim.system.SystemDescription.trace_names)
#: that this layout places.
TRACE_KEYS: tuple[str, ...] = tuple(key for key, *_ in _SERIES)
#: what a fleet recording places (the 3D scene and per-vehicle views): no ybar, no zhat,
#: which the per-vehicle deployment does not have (no reference sensor; each vehicle its
#: own estimate of the leader)
FLEET_TRACE_KEYS: tuple[str, ...] = ("e", "u", "x", "xhat", "w", "what", "z")

#: Blueprint view groups: (view name prefix == entity root, trace keys whose dims count).
VIEW_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("error", ("e",)),
    ("state", ("x", "xhat")),
    ("control", ("u",)),
    ("disturbance", ("w", "what")),
    ("reference", ("z", "zhat")),
)

#: each estimator's colour (its registry row)
_FIXED_COLORS: dict[str, tuple[int, int, int]] = {k: e.color for k, e in ESTIMATORS.items()}
#: (line width, alpha) of the estimators drawn wide and translucent (the ideal one, whose
#: trace is nearly the Kalman filter's): under the others, showing round them
_WIDE: dict[str, tuple[float, int]] = {k: e.wide for k, e in ESTIMATORS.items()
                                       if e.wide is not None}
_PALETTE: tuple[tuple[int, int, int], ...] = (
    (214, 39, 40),    # red
    (148, 103, 189),  # purple
    (140, 86, 75),    # brown
    (227, 119, 194),  # pink
    (127, 127, 127),  # grey
    (188, 189, 34),   # olive
    (23, 190, 207),   # cyan
)

#: colour of the true signal in the paper layout (drawn once, under the estimates)
TRUE_COLOR: tuple[int, int, int] = (235, 235, 235)       # on the viewer's dark background
#: one hue per component of a vehicle's series (north, east, down, then further states)
_AXIS_COLORS: tuple[tuple[int, int, int], ...] = (
    (214, 39, 40), (44, 160, 44), (31, 119, 180), (255, 127, 14), (148, 103, 189),
    (140, 86, 75))
_COLOR_NAMES: dict[tuple[int, int, int], str] = {
    (31, 119, 180): "blue", (255, 127, 14): "orange", (44, 160, 44): "green",
    (214, 39, 40): "red", (148, 103, 189): "purple", (140, 86, 75): "brown",
    (227, 119, 194): "pink", (127, 127, 127): "grey", (188, 189, 34): "olive",
    (23, 190, 207): "cyan", TRUE_COLOR: "white"}

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

    Parameters
    ----------
    methods : list[str] or tuple[str, ...]
        Method names (estimator modes or any label).

    Returns
    -------
    dict[str, tuple[int, int, int]]
        Method -> (red, green, blue), 0-255.
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


#: line width of a method's traces (viewer points; matplotlib scales it by _MPL_WIDTH)
_LINE_WIDTH = 1.0
#: dash patterns of the thin methods in matplotlib, in the methods' order (the viewer draws
#: every line solid: there, colour, width and drawing order tell them apart)
_DASHES: tuple[str, ...] = ("-", "--", ":", "-.")
#: the viewer's opacity of a thin method drawn over a wide one (:class:`MethodStyle`)
_OVER_WIDE_ALPHA = 140


@dataclass(frozen=True)
class MethodStyle:
    """How one method's traces are drawn, the same in the viewer and in matplotlib: every
    method differs from every other in colour and in width or dash, and the wide translucent
    ones (the ideal estimator, whose curve is nearly the Kalman filter's) are drawn first,
    so the thin line of the nearly equal method shows on top and the wide one round it."""

    color: tuple[int, int, int]     #: RGB 0-255
    width: float                    #: line width (viewer points)
    alpha: int                      #: opacity 0-255
    dash: str                       #: matplotlib line style ("-", "--", ":", "-.")
    layer: int                      #: drawing order among the methods: 0 first (at the back)
    #: opacity in the viewer, which draws a view's series in the order of their entity
    #: paths (``error/1/classical`` < ``error/1/ideal`` < ``error/1/kalman``), each as the
    #: min-max band of its noise when zoomed out: a thin method drawn after a wide one is
    #: translucent there, so the wide one's band shows through it; the wide one is opaque
    viewer_alpha: int = 255

    @property
    def wide(self) -> bool:
        """Whether it is a wide translucent line (drawn under the thin ones)."""
        return self.width > _LINE_WIDTH


def method_styles(methods: list[str] | tuple[str, ...]) -> dict[str, MethodStyle]:
    """The :class:`MethodStyle` of each method: its colour (:func:`method_color`); the
    width and opacity of its registry row (``wide``: the ideal estimator, 3 points at
    150/255) or a thin opaque line with a dash of its own (solid, dashed, dotted,
    dash-dotted in the methods' order; after four, the colour alone tells them apart);
    wide methods in the back layers; in the viewer (``viewer_alpha``) the wide ones opaque
    and a thin one drawn over them translucent.

    Parameters
    ----------
    methods : list[str] or tuple[str, ...]
        Method names in the recording's order.

    Returns
    -------
    dict[str, MethodStyle]
        Method -> style, in the order of ``methods``.
    """
    colors = method_color(methods)
    wide = [m for m in methods if m in _WIDE]
    thin = [m for m in methods if m not in _WIDE]
    order = wide + thin
    out = {}
    for m in methods:
        width, alpha = _WIDE.get(m, (_LINE_WIDTH, 255))
        dash = "-" if m in _WIDE else _DASHES[thin.index(m) % len(_DASHES)]
        over_wide = m not in _WIDE and any(w < m for w in wide)     # entity path order
        out[m] = MethodStyle(colors[m], float(width), int(alpha), dash, order.index(m),
                             _OVER_WIDE_ALPHA if over_wide else 255)
    return out


#: (width, alpha) of the first method's per-vehicle lines when a fleet recording holds more
#: than one method: wide and see-through, so the others' thin lines show on it or through it
_FLEET_FIRST_LINE = (2.5, 150)


def fleet_method_line(method_index: int, n_methods: int) -> tuple[float, int]:
    """(width, alpha) of a method's per-vehicle series in a fleet recording. Its components
    have one hue each (:func:`axis_colors`), a method a shade of them; on the viewer's dark
    background a darker shade alone hardly shows, so with two methods or more the first
    is also drawn wide and see-through and the others thin and opaque: whichever the
    viewer draws last (entity-path order), both show.

    Parameters
    ----------
    method_index : int
        Position of the method in the recording (0-based).
    n_methods : int
        Methods in the recording.

    Returns
    -------
    tuple[float, int]
        Line width (points) and alpha (0-255).
    """
    if n_methods > 1 and method_index == 0:
        return _FLEET_FIRST_LINE
    return (_LINE_WIDTH, 255)


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
    #: unit of the errors / controls in the view names; None: from the component names
    #: (n, e, d: m; X_n, X_e, X_d: N), see :func:`orchestrator.recording.ranges.unit_of`.
    error_unit: str | None = None
    control_unit: str | None = None
    #: the nonlinear vehicle's actuator limits drawn in its actuator views: propeller speed
    #: (rpm) and fin angle (rad); None: the REMUS 100 defaults (1525 rpm, 15 deg).
    n_max: float | None = None
    delta_max: float | None = None

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
    error_unit: str | None = None
    control_unit: str | None = None
    n_max: float | None = None
    delta_max: float | None = None


def _shade(rgb: tuple[int, int, int], k: int) -> tuple[int, int, int]:
    """Shade k of a colour: 0 the colour itself, then alternately darker and lighter."""
    if k == 0:
        return rgb
    amount = min(0.25 + 0.1 * ((k + 1) // 2), 0.7)
    if k % 2:  # darker: blend towards black
        return tuple(round(c * (1.0 - amount)) for c in rgb)  # type: ignore[return-value]
    return _lighter(rgb, amount)


def color_name(rgb: tuple[int, int, int]) -> str:
    """The name of one of the layout's colours (for the legend view)."""
    return _COLOR_NAMES.get(tuple(int(c) for c in rgb), f"rgb{tuple(rgb)}")


def axis_colors(count: int, method_index: int) -> list[tuple[int, int, int]]:
    """Colours of the ``count`` components of one method's vehicle series: one hue per
    component (north red, east green, down blue, ...); the first method in full colour,
    the second darker, the third lighter, and so on.

    Parameters
    ----------
    count : int
        Components.
    method_index : int
        Position of the method in the recording (0-based).

    Returns
    -------
    list[tuple[int, int, int]]
        RGB 0-255 per component.
    """
    return [_shade(_AXIS_COLORS[c % len(_AXIS_COLORS)], method_index) for c in range(count)]


def _vehicle_colors(n: int) -> np.ndarray:
    """(n, 3) uint8: one hue per vehicle, evenly spread round the colour wheel."""
    rgb = [colorsys.hsv_to_rgb(i / n, 0.75, 0.95) for i in range(n)]
    return np.round(np.asarray(rgb) * 255.0).astype(np.uint8).reshape(n, 3)
