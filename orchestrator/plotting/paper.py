"""The paper's figures 2-7 from a recording in the paper layout: ``error-i``, ``state-i`` and
``control-i`` for every component i, the recorded methods overlaid in the recording's
colours (:func:`orchestrator.recording.method_color`).

Each figure has two columns: the whole run, each trace as the envelope of its noise (the
minimum and maximum per time bin as a band, the bin mean as a line), the zoomed window
marked; and a zoom of 20 s after the start-up transient (from the start of the statistics
window) where every sample is drawn, so that the methods' traces can be told apart.

The state figures draw each method's true state and its estimate (in the method's lighter
colour, as in the viewer), one row per method. Their y-axis is scaled to the true states
(and to the estimates that stay near them): an estimate that leaves that range by far, such
as the classical law's spikes, is not drawn; a note in its panel gives its range.
"""
from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes

from orchestrator.recording import method_color

from .figure import (
    PlotFigure,
    axis_label,
    estimate_rgb,
    legend_outside,
    line_styles,
    new_figure,
    rgb,
)
from .run_folder import RunData
from .window import BINS, draw_envelope, finite_limits, zoom_window

__all__ = ["PAPER_FIGURES", "paper_figures"]

#: (entity root, figure title ({sym}: the quantity), quantity symbol) of figures 2-7, in the
#: paper's order
PAPER_FIGURES: tuple[tuple[str, str, str], ...] = (
    ("error", "Tracking error {sym}", "e"),
    ("state", "State {sym} and its estimate", "x"),
    ("control", "Control input {sym}", "u"),
)

#: An estimate is kept inside the y-axis if it stays within this many spans of the true
#: states beyond their range on either side; else it is drawn clipped.
_NEAR = 0.5
#: Margin added on either side of the y-range, as a fraction of the range.
_MARGIN = 0.06

_WIDTH, _HEIGHT = 9.0, 4.2


def _seconds(sim_time: np.ndarray) -> np.ndarray:
    return sim_time.astype(np.float64) / 1e9


def _title(run: RunData, text: str, note: str = "") -> str:
    seed = "" if run.seed is None else f", seed {run.seed}"
    head = f"{text} — scenario {run.scenario}{seed}, {' vs '.join(run.methods)}"
    if run.label:
        head += f" ({run.label})"
    return head + (f"\n{note}" if note else "")


def _range(v: np.ndarray) -> tuple[float, float] | None:
    """(min, max) of the finite values (a diverged run holds inf / nan), None if none."""
    finite = v[np.isfinite(v)]
    return (float(finite.min()), float(finite.max())) if finite.size else None


def _spread(v: np.ndarray) -> float:
    """Standard deviation of a series; inf if it holds inf / nan (a diverged run)."""
    return float(np.std(v)) if np.all(np.isfinite(v)) else float("inf")


def _limits(trues: list[np.ndarray], estimates: dict[str, np.ndarray]
            ) -> tuple[tuple[float, float], dict[str, tuple[float, float]]]:
    """y-limits covering the true signals and the estimates near them; the estimates left
    out, with their (min, max) (finite values only)."""
    ranges = [r for r in map(_range, trues) if r is not None] or [(-1.0, 1.0)]
    lo, hi = min(r[0] for r in ranges), max(r[1] for r in ranges)
    span = hi - lo if hi > lo else max(abs(hi), 1.0)
    near = (lo - _NEAR * span, hi + _NEAR * span)
    far: dict[str, tuple[float, float]] = {}
    for key, v in estimates.items():
        r = _range(v)
        if r is None:
            continue
        if r[0] >= near[0] and r[1] <= near[1]:
            lo, hi = min(lo, r[0]), max(hi, r[1])
        else:
            far[key] = r
    pad = _MARGIN * (hi - lo if hi > lo else max(abs(hi), 1.0))
    ylim = (lo - pad, hi + pad)
    clipped = {k: r for k, r in far.items() if r[0] < ylim[0] or r[1] > ylim[1]}
    return ylim, clipped


def _panels(run: RunData, rows: int, height: float) -> tuple[PlotFigure, np.ndarray, float,
                                                             tuple[float, float]]:
    """A figure of ``rows`` x 2 panels (the whole run, the zoom), its name left blank; the
    run's end time and the zoomed window."""
    fig, axes = new_figure(_WIDTH + 2.6, height, rows, 2, sharex="col",
                           gridspec_kw={"width_ratios": [2.0, 1.0]})
    t_end = max(float(_seconds(t)[-1]) for _, t, _ in run.scalars.values() if len(t))
    return PlotFigure("", fig), axes, t_end, zoom_window(run.summary, t_end)


def _frame(ax_whole: Axes, ax_zoom: Axes, zoom: tuple[float, float], n: int,
           t_end: float) -> None:
    """Titles, the zoomed window marked on the whole run, and the zoom's x-range."""
    ax_whole.axvspan(*zoom, color="0.88", zorder=0, lw=0)
    binned = n >= 2 * BINS
    ax_whole.set_title("whole run" + (f": min-max per {t_end / BINS:.2g} s bin (band) and "
                                      "bin mean (line)" if binned else ""), loc="left",
                       fontsize=9)
    ax_zoom.set_title(f"zoom: t in [{zoom[0]:.4g}, {zoom[1]:.4g}] s, every sample (grey on "
                      "the left)", loc="left", fontsize=9)
    ax_whole.set_xlim(0.0, t_end)
    ax_zoom.set_xlim(*zoom)


def _simple_figure(run: RunData, root: str, i: int, title: str, symbol: str) -> PlotFigure:
    """error-i or control-i: left, the whole run of every method as the envelope of its
    noise (min-max band per bin, bin mean), its full range shown; right, a zoom of
    :data:`~.window.ZOOM_S` s after the start-up transient, every sample drawn. Each method
    has its own colour and dash or width in the whole run (:func:`~.figure.line_styles`;
    the zoom draws every sample solid): the ideal estimator's wide translucent line lies
    under the Kalman filter's thin one; every band under every line, the widest band and
    the noisiest line at the back."""
    spread = {m: _spread(run.scalars[f"{root}/{i}/{m}"][2]) for m in run.methods}
    styles = line_styles(run.methods, spread)
    pf, axes, t_end, zoom = _panels(run, 1, _HEIGHT)
    pf.name = f"{root}-{i}"
    whole, zoomed = axes[0]
    back_to_front = sorted(run.methods, key=lambda m: -spread[m])
    n = 0
    for m in run.methods:
        entity = f"{root}/{i}/{m}"
        _, t, v = run.scalars[entity]
        n = len(v)
        band_z = 1 + back_to_front.index(m) / len(back_to_front)   # widest band at the back
        pf.whole[entity] = draw_envelope(whole, _seconds(t), v, styles[m].color, label=m,
                                         line=styles[m].kw(), band_zorder=band_z)
        (line,) = zoomed.plot(_seconds(t), v, label=m, **{**styles[m].kw(), "ls": "-"})
        pf.series[entity] = line
    _frame(whole, zoomed, zoom, n, t_end)
    lim = finite_limits([(_seconds(t), v) for _, t, v in
                         (run.scalars[f"{root}/{i}/{m}"] for m in run.methods)], *zoom)
    if lim is not None:
        zoomed.set_ylim(*lim)
    for ax in (whole, zoomed):
        ax.set_xlabel("time t (s)")
    whole.set_ylabel(axis_label(f"${symbol}_{{{i}}}$", None))
    pf.figure.suptitle(_title(run, title.format(sym=f"${symbol}_{{{i}}}$")), fontsize=10)
    legend_outside(zoomed, handles=[pf.whole[f"{root}/{i}/{m}"] for m in run.methods])
    return pf


def _state_figure(run: RunData, i: int, title: str, symbol: str) -> PlotFigure:
    """state-i: one row per method with its true state and its estimate, the whole run
    (envelope of the noise) on the left and a zoom after the transient on the right; the
    common y-axis scaled to the true states and the estimates near them. An estimate far
    outside it (the classical law's spikes) is not drawn: a note in its panel gives its
    range.

    The true state differs between methods (each method's controls drive it; only the
    noise is shared), so the methods are one row each, not overlaid."""
    colors = method_color(run.methods)
    k = len(run.methods)
    pf, axes, t_end, zoom = _panels(run, k, _HEIGHT if k == 1 else 1.1 + 2.3 * k)
    pf.name = f"state-{i}"
    true = {m: run.scalars[f"state/{i}/{m}/true"] for m in run.methods}
    est = {m: run.scalars[f"state/{i}/{m}/estimate"] for m in run.methods}
    ylim, clipped = _limits([v for _, _, v in true.values()],
                            {m: v for m, (_, _, v) in est.items()})
    shown = [(_seconds(t), v) for _, t, v in true.values()] + [
        (_seconds(t), v) for m, (_, t, v) in est.items() if m not in clipped]
    zlim = finite_limits(shown, *zoom)
    sym = f"${symbol}_{{{i}}}$"
    for (whole, zoomed), m in zip(axes, run.methods):
        _, t, v = true[m]
        draw_envelope(whole, _seconds(t), v, rgb(colors[m]), zorder=2)
        (line,) = zoomed.plot(_seconds(t), v, color=rgb(colors[m]), zorder=2,
                              label=f"{m} true")
        pf.series[f"state/{i}/{m}/true"] = line
        _, t, v = est[m]
        if m in clipped:
            lo, hi = clipped[m]
            pf.clipped[f"state/{i}/{m}/estimate"] = clipped[m]
            whole.text(0.01, 0.97, f"{m} estimate off this scale: it spans {lo:.3g} to "
                                   f"{hi:.3g} (not drawn)", transform=whole.transAxes,
                       va="top", ha="left", fontsize=8, zorder=6,
                       bbox={"boxstyle": "round,pad=0.3", "fc": "white", "ec": "0.6"})
        else:
            label, z = f"{m} estimate", 3
            if np.array_equal(v, true[m][2]):
                label, z = label + "\n(= true state, drawn under it)", 1
            draw_envelope(whole, _seconds(t), v, estimate_rgb(colors[m]), zorder=z)
            (line,) = zoomed.plot(_seconds(t), v, color=estimate_rgb(colors[m]), label=label,
                                  zorder=z)
            pf.series[f"state/{i}/{m}/estimate"] = line
        _frame(whole, zoomed, zoom, len(v), t_end)
        whole.set_ylim(*ylim)
        if zlim is not None:
            zoomed.set_ylim(*zlim)
        whole.set_ylabel(axis_label(sym, None))
        legend_outside(zoomed)
    for ax in axes[-1]:
        ax.set_xlabel("time t (s)")
    note = ""
    if clipped:
        names = ", ".join(clipped)
        note = (f"y-axis scaled to the true states: the {names} estimate"
                f"{'s leave' if len(clipped) > 1 else ' leaves'} it (range in the panel)")
    pf.figure.suptitle(_title(run, title.format(sym=sym), note), fontsize=10)
    return pf


def paper_figures(run: RunData) -> list[PlotFigure]:
    """Figures 2-7 of a paper-layout recording: error-i, state-i, control-i per component.

    Parameters
    ----------
    run : RunData
        A run folder read by :func:`orchestrator.plotting.run_folder.load_run` whose
        recording is in the paper layout.

    Returns
    -------
    list[PlotFigure]
        ``error-1``, ``error-2``, ..., ``state-1``, ..., ``control-1``, ... in that order.
        The paper's example is unitless: axes say "model units".
    """
    out: list[PlotFigure] = []
    for root, title, symbol in PAPER_FIGURES:
        for i in range(1, run.components(root) + 1):
            if root == "state":
                out.append(_state_figure(run, i, title, symbol))
            else:
                out.append(_simple_figure(run, root, i, title, symbol))
    return out
