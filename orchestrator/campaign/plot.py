"""Plots of a campaign: the cost rate against each swept parameter, with its band.

One SVG per swept key (``cost_<key>.svg``, no plotting library needed): x is the parameter
(numbers on a linear axis, anything else as equally spaced categories), y the mean cost
rate over seeds (per second) with its 95 % confidence interval as a band (error bars for
categories), and the prediction as a dashed line with open markers; the y axis labelled,
its ticks round numbers (:func:`nice_ticks`). Points that differ in the other swept keys
are separate series, named by those values in full in the legend (wrapped, never cut).
"""
from __future__ import annotations

import json
import math
from html import escape
from pathlib import Path
from typing import Any

from ..atomic import write_text_atomically
from .points import param_text

__all__ = ["cost_plot_svg", "legend_lines", "nice_ticks", "write_plots"]

_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2",
            "#17becf")
W, H, L, R, T, B = 760, 420, 80, 240, 40, 60
#: characters per line of a legend label (a longer label wraps at its spaces, never cut)
LEGEND_WRAP = 30
#: the y axis's label
Y_LABEL = "cost rate J/T (cost per second)"


def nice_ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    """Round ticks covering [lo, hi]: a step of 1, 2, 2.5 or 5 times a power of ten giving
    about ``n`` intervals, the first tick at or below ``lo`` and the last at or above
    ``hi`` (the axis's limits).

    Parameters
    ----------
    lo, hi : float
        The range of the data.
    n : int, optional
        About this many intervals.

    Returns
    -------
    list[float]
    """
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return [0.0, 1.0]
    if hi <= lo:
        lo, hi = lo - (abs(lo) or 1.0) * 0.5, hi + (abs(hi) or 1.0) * 0.5
    raw = (hi - lo) / n
    power = 10.0 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * power >= raw * (1 - 1e-9))
    first, last = math.floor(lo / step + 1e-9), math.ceil(hi / step - 1e-9)
    return [round(k * step, 12) for k in range(first, last + 1)]


def _tick_text(v: float, ticks: list[float]) -> str:
    """A tick's label with the decimals the step needs (``0.25``, ``600``, ``1.5e+04``)."""
    step = ticks[1] - ticks[0] if len(ticks) > 1 else 1.0
    decimals = max(0, -math.floor(math.log10(step) + 1e-9) + (1 if round(
        step / 10.0 ** math.floor(math.log10(step)), 6) == 2.5 else 0))
    if max(abs(ticks[0]), abs(ticks[-1])) >= 1e6 or (step < 1e-4):
        return f"{v:.3g}"
    return f"{v:.{decimals}f}"


def legend_lines(label: str, width: int = LEGEND_WRAP) -> list[str]:
    """A legend label in lines of at most ``width`` characters, broken at spaces (a word
    longer than that stays whole): joined with spaces they give the label back."""
    import textwrap
    return textwrap.wrap(label, width, break_long_words=False, break_on_hyphens=False) or [label]


def _numeric(values: list[Any]) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def cost_plot_svg(agg: list[dict[str, Any]], key: str) -> str | None:
    """The SVG text of the cost rate against the swept ``key`` (None if nothing to plot).

    Parameters
    ----------
    agg : list[dict[str, Any]]
        Aggregate rows (:func:`.aggregate.aggregate_rows`).
    key : str
        A swept dotted key.

    Returns
    -------
    str or None
    """
    rows = [a for a in agg if a.get("cost_rate_mean") is not None]
    if not rows:
        return None
    params = [json.loads(a["params"]) for a in rows]
    xs_all = [p.get(key) for p in params]
    numeric = _numeric(xs_all)
    cats = list(dict.fromkeys(param_text(x) for x in xs_all))
    series: dict[str, list[tuple[Any, dict]]] = {}
    for a, p in zip(rows, params):
        label = ", ".join(f"{k}={param_text(v)}" for k, v in p.items() if k != key) or "all"
        series.setdefault(label, []).append((p.get(key), a))
    ys = [v for a in rows for v in (a["cost_rate_ci_low"], a["cost_rate_ci_high"],
                                    a.get("predicted_cost_rate")) if v is not None]
    y0, y1 = min(ys), max(ys)
    pad = 0.06 * (y1 - y0 or abs(y1) or 1.0)
    y0, y1 = y0 - pad, y1 + pad                      # the axis: the data and a margin,
    yticks = [v for v in nice_ticks(y0, y1) if y0 <= v <= y1]   # round ticks inside it
    wrapped = {label: legend_lines(label) for label in series}
    height = max(H, T + 16 * sum(len(w) + 0.3 for w in wrapped.values()) + 20)
    if numeric:
        x0, x1 = min(xs_all), max(xs_all)
        if x0 == x1:
            x0, x1 = x0 - 1, x1 + 1

        def X(v: Any) -> float:
            return L + (float(v) - x0) / (x1 - x0) * (W - L - R)
    else:
        def X(v: Any) -> float:
            return L + (cats.index(param_text(v)) + 0.5) / len(cats) * (W - L - R)

    def Y(v: float) -> float:
        return T + (y1 - v) / (y1 - y0) * (H - T - B)

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{height:.0f}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="{W}" height="{height:.0f}" fill="white"/>',
           f'<text x="{W / 2}" y="20" text-anchor="middle" font-size="14">cost rate J/T '
           f'against {escape(key)} (mean, 95 % CI; dashed: predicted)</text>',
           f'<line x1="{L}" y1="{H - B}" x2="{W - R}" y2="{H - B}" stroke="black"/>',
           f'<line x1="{L}" y1="{T}" x2="{L}" y2="{H - B}" stroke="black"/>']
    for v in yticks:
        out.append(f'<line x1="{L - 4}" y1="{Y(v):.1f}" x2="{W - R}" y2="{Y(v):.1f}" '
                   'stroke="#dddddd"/>')
        out.append(f'<text class="ytick" x="{L - 6}" y="{Y(v) + 4:.1f}" '
                   f'text-anchor="end">{_tick_text(v, yticks)}</text>')
    yc = (T + H - B) / 2
    out.append(f'<text class="ylabel" x="18" y="{yc:.1f}" text-anchor="middle" '
               f'transform="rotate(-90 18 {yc:.1f})">{escape(Y_LABEL)}</text>')
    ticks = sorted(set(xs_all)) if numeric else cats
    for t in ticks:
        out.append(f'<text x="{X(t):.1f}" y="{H - B + 16}" text-anchor="middle">'
                   f'{escape(param_text(t))}</text>')
    out.append(f'<text x="{(L + W - R) / 2}" y="{H - 12}" text-anchor="middle">'
               f'{escape(key)}</text>')
    legend_y = float(T)
    for j, (label, pts) in enumerate(series.items()):
        c = _COLOURS[j % len(_COLOURS)]
        pts = sorted(pts, key=lambda q: float(q[0]) if numeric else cats.index(param_text(q[0])))
        if numeric and len(pts) > 1:
            band = [(X(x), Y(a["cost_rate_ci_high"])) for x, a in pts] + \
                   [(X(x), Y(a["cost_rate_ci_low"])) for x, a in reversed(pts)]
            out.append(f'<polygon points="{" ".join(f"{u:.1f},{v:.1f}" for u, v in band)}" '
                       f'fill="{c}" fill-opacity="0.2" stroke="none"/>')
        line = " ".join(f"{X(x):.1f},{Y(a['cost_rate_mean']):.1f}" for x, a in pts)
        out.append(f'<polyline points="{line}" fill="none" stroke="{c}" stroke-width="2"/>')
        pred = [(x, a["predicted_cost_rate"]) for x, a in pts
                if a.get("predicted_cost_rate") is not None and math.isfinite(
                    a["predicted_cost_rate"])]
        if pred:
            out.append('<polyline points="' + " ".join(f"{X(x):.1f},{Y(v):.1f}" for x, v in pred)
                       + f'" fill="none" stroke="{c}" stroke-dasharray="5,4"/>')
        for x, a in pts:
            xv = X(x)
            out.append(f'<line x1="{xv:.1f}" y1="{Y(a["cost_rate_ci_low"]):.1f}" x2="{xv:.1f}" '
                       f'y2="{Y(a["cost_rate_ci_high"]):.1f}" stroke="{c}"/>')
            out.append(f'<circle cx="{xv:.1f}" cy="{Y(a["cost_rate_mean"]):.1f}" r="3.5" '
                       f'fill="{c}"><title>{escape(label)}: {a["cost_rate_mean"]:.6g} '
                       f'[{a["cost_rate_ci_low"]:.6g}, {a["cost_rate_ci_high"]:.6g}]'
                       f'</title></circle>')
        for x, v in pred:
            out.append(f'<circle cx="{X(x):.1f}" cy="{Y(v):.1f}" r="4" fill="none" '
                       f'stroke="{c}"/>')
        lines = "".join(f'<tspan x="{W - R + 28}" dy="{0 if k == 0 else 15}">'
                        f'{escape(part)}</tspan>' for k, part in enumerate(wrapped[label]))
        out.append(f'<g class="legend-entry"><title>{escape(label)}</title>'
                   f'<rect x="{W - R + 12}" y="{legend_y:.0f}" width="10" height="10" '
                   f'fill="{c}"/><text x="{W - R + 28}" y="{legend_y + 10:.0f}">{lines}'
                   '</text></g>')
        legend_y += 15 * len(wrapped[label]) + 5
    out.append("</svg>")
    return "\n".join(out) + "\n"


def write_plots(agg: list[dict[str, Any]], out: Path) -> list[Path]:
    """Write ``cost_<key>.svg`` for every swept key of the aggregate.

    Parameters
    ----------
    agg : list[dict[str, Any]]
        Aggregate rows.
    out : Path
        The output folder.

    Returns
    -------
    list[Path]
        The files written.
    """
    keys = list(dict.fromkeys(k for a in agg for k in json.loads(a["params"])))
    written = []
    for key in keys:
        svg = cost_plot_svg(agg, key)
        if svg is not None:
            path = out / f"cost_{key.replace('/', '_')}.svg"
            write_text_atomically(path, svg)
            written.append(path)
    return written
