"""Plots of a campaign: the cost rate against each swept parameter, with its band.

One SVG per swept key (``cost_<key>.svg``, no plotting library needed): x is the parameter
(numbers on a linear axis, anything else as equally spaced categories), y the mean cost
rate over seeds (per second) with its 95 % confidence interval as a band (error bars for
categories), and the prediction as a dashed line with open markers. Points that differ in
the other swept keys are separate series, named by those values.
"""
from __future__ import annotations

import json
import math
from html import escape
from pathlib import Path
from typing import Any

from ..atomic import write_text_atomically
from .points import param_text

__all__ = ["write_plots", "cost_plot_svg"]

_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2",
            "#17becf")
W, H, L, R, T, B = 720, 420, 80, 200, 40, 60


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
    pad = 0.08 * (y1 - y0 or abs(y1) or 1.0)
    y0, y1 = y0 - pad, y1 + pad
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

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="{W}" height="{H}" fill="white"/>',
           f'<text x="{W / 2}" y="20" text-anchor="middle" font-size="14">cost rate J/T '
           f'against {escape(key)} (mean, 95 % CI; dashed: predicted)</text>',
           f'<line x1="{L}" y1="{H - B}" x2="{W - R}" y2="{H - B}" stroke="black"/>',
           f'<line x1="{L}" y1="{T}" x2="{L}" y2="{H - B}" stroke="black"/>']
    for i in range(5):
        v = y0 + i * (y1 - y0) / 4
        out.append(f'<text x="{L - 6}" y="{Y(v) + 4:.1f}" text-anchor="end">{v:.4g}</text>')
    ticks = sorted(set(xs_all)) if numeric else cats
    for t in ticks:
        out.append(f'<text x="{X(t):.1f}" y="{H - B + 16}" text-anchor="middle">'
                   f'{escape(param_text(t))}</text>')
    out.append(f'<text x="{(L + W - R) / 2}" y="{H - 12}" text-anchor="middle">'
               f'{escape(key)}</text>')
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
        out.append(f'<rect x="{W - R + 12}" y="{T + 18 * j}" width="10" height="10" '
                   f'fill="{c}"/><text x="{W - R + 28}" y="{T + 18 * j + 10}">'
                   f'{escape(label[:28])}</text>')
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
