"""The y-axis of every time-series view: a range that covers the data and holds at least three
labelled ticks, and the units the view names carry.

The Rerun 0.41 viewer labels its y-axis at multiples of a power of ten (1, 10, 100, ...) and
only labels a step whose ticks are far enough apart on screen; a view whose range spans, say,
-8 to 8 over 150 pixels shows a single "0". :func:`tick_range` widens a range to hold three
multiples of the largest power of ten that fits in its span, so that step is labelled.
"""
from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

__all__ = ["DIMENSIONLESS", "data_range", "tick_range", "unit_of"]

#: the unit of the paper example's signals (its model has no physical units)
DIMENSIONLESS = "dimensionless"
#: margin added to each side of the data, as a share of its span
_MARGIN = 0.05
_MIN_TICKS = 3
#: more ticks than this of one step in a view: the viewer draws their labels faint
_MAX_TICKS = 4.5
#: the least share of the view the data must fill when the ticks go to the next power of ten
_MIN_FILL = 0.4


def tick_range(lo: float, hi: float, margin: float = _MARGIN) -> tuple[float, float]:
    """``[lo, hi]`` widened by ``margin`` of its span on each side, then to hold at least
    three multiples of the power of ten d = 10**floor(log10(span)) (the tick step the viewer
    labels), the extra multiples taken on the nearer side, plus a little room past them.
    When the span holds more than 4.5 steps d (labels too close: drawn faint), 10 d is
    used instead if the data still fill 40 % of the view.

    Parameters
    ----------
    lo, hi : float
        The data's extremes (hi >= lo; equal for a constant).
    margin : float, optional
        Share of the span added on each side before the ticks are counted.

    Returns
    -------
    tuple[float, float]
        (low, high) of the axis; holds [lo, hi] and at least three multiples of d.
    """
    lo, hi = float(lo), float(hi)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return -1.0, 1.0
    if hi < lo:
        lo, hi = hi, lo
    span = hi - lo
    if span <= 1e-12 * max(1.0, abs(lo), abs(hi)):        # a constant: a unit-wide band
        pad = max(abs(lo), 1.0) * 0.5
        lo, hi = lo - pad, hi + pad
        span = hi - lo
    lo, hi = lo - margin * span, hi + margin * span
    step = 10.0 ** math.floor(math.log10(hi - lo))
    view = _with_ticks(lo, hi, step)
    if (hi - lo) / step > _MAX_TICKS:      # ticks too close to be labelled brightly:
        wide = _with_ticks(lo, hi, 10.0 * step)     # the next power of ten, if the data
        if (hi - lo) / (wide[1] - wide[0]) >= _MIN_FILL:   # still fill enough of the view
            view = wide
    return view


def _with_ticks(lo: float, hi: float, step: float) -> tuple[float, float]:
    """[lo, hi] widened to hold three multiples of ``step`` (the nearer ones), with room."""
    first, last = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
    while last - first + 1 < _MIN_TICKS:                   # add the nearer multiple
        if lo - (first - 1) * step <= (last + 1) * step - hi:
            first -= 1
        else:
            last += 1
    room = 0.04 * (last - first) * step                    # labels at the ends stay inside
    return min(lo, first * step - room), max(hi, last * step + room)


def data_range(arrays: Iterable[np.ndarray], margin: float = _MARGIN) -> tuple[float, float]:
    """:func:`tick_range` of the finite values of ``arrays`` together ((-1, 1) if none).

    Parameters
    ----------
    arrays : Iterable[np.ndarray]
        Everything the view draws.
    margin : float, optional
        As in :func:`tick_range`.

    Returns
    -------
    tuple[float, float]
        (low, high).
    """
    los, his = [], []
    for a in arrays:
        a = np.asarray(a, dtype=float)
        a = a[np.isfinite(a)]
        if a.size:
            los.append(float(a.min()))
            his.append(float(a.max()))
    if not los:
        return tick_range(-1.0, 1.0, margin)
    return tick_range(min(los), max(his), margin)


#: units of the fleet models' component names (plant_model.vehicles)
_NAME_UNITS = {"n": "m", "e": "m", "d": "m", "north": "m", "east": "m", "down": "m",
               "X_n": "N", "X_e": "N", "X_d": "N", "v_n": "m/s", "v_e": "m/s", "v_d": "m/s",
               "v_cn": "m/s", "v_ce": "m/s", "v_cd": "m/s", "u": "m/s", "v": "m/s",
               "w": "m/s", "phi": "rad", "theta": "rad", "psi": "rad"}


def unit_of(names: Iterable[str], given: str | None = None) -> str:
    """The unit a view of the components ``names`` shows: ``given`` if set, else the one
    unit every name has in the fleet models (n, e, d: m; X_n, X_e, X_d: N; v_*: m/s), else
    the units joined with "/" in the components' order, "model units" for unknown names.

    Parameters
    ----------
    names : Iterable[str]
        The components' names.
    given : str or None, optional
        An explicit unit (FleetLayout's ``error_unit`` / ``control_unit``).

    Returns
    -------
    str
        E.g. "m", "N", "m, m/s".
    """
    if given:
        return given
    units = [_NAME_UNITS.get(n) for n in names]
    if not units or any(u is None for u in units):
        return "model units"
    distinct = list(dict.fromkeys(units))
    return ", ".join(distinct)  # type: ignore[arg-type]
