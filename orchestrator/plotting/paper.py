"""The paper's figures 2-7 from a recording in the paper layout: ``error-i``, ``state-i`` and
``control-i`` for every component i, the recorded methods overlaid in the recording's
colours (:func:`orchestrator.recording.method_color`).

The state figures draw each method's true state and its estimate (in the method's lighter
colour, as in the viewer). Their y-axis is scaled to the true states (and to the estimates
that stay near them): an estimate that leaves that range by far, such as the classical
law's spikes, is drawn clipped by the axes, and the title and its legend entry say so.
"""
from __future__ import annotations

import numpy as np

from orchestrator.recording import method_color

from .figure import PlotFigure, axis_label, estimate_rgb, legend_outside, new_figure, rgb
from .run_folder import RunData

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


def _simple_figure(run: RunData, root: str, i: int, title: str, symbol: str) -> PlotFigure:
    """error-i or control-i: one line per method overlaid, the full range shown (these are
    the signals the methods are compared by: nothing is clipped)."""
    colors = method_color(run.methods)
    fig, axes = new_figure(_WIDTH, _HEIGHT)
    ax = axes[0, 0]
    pf = PlotFigure(f"{root}-{i}", fig)
    spread = {m: _spread(run.scalars[f"{root}/{i}/{m}"][2]) for m in run.methods}
    back_to_front = sorted(run.methods, key=lambda m: -spread[m])
    for m in run.methods:           # the widest series at the back: the others stay visible
        entity = f"{root}/{i}/{m}"
        _, t, v = run.scalars[entity]
        (line,) = ax.plot(_seconds(t), v, color=rgb(colors[m]), label=m,
                          zorder=2 + back_to_front.index(m) / len(back_to_front))
        pf.series[entity] = line
    ax.set_xlabel("time t (s)")
    ax.set_ylabel(axis_label(f"${symbol}_{{{i}}}$", None))
    ax.set_title(_title(run, title.format(sym=f"${symbol}_{{{i}}}$")))
    ax.margins(x=0.0)
    legend_outside(ax)
    return pf


def _state_figure(run: RunData, i: int, title: str, symbol: str) -> PlotFigure:
    """state-i: one panel per method (same axes) with its true state and its estimate; the
    common y-axis scaled to the true states and the estimates near them.

    The true state differs between methods (each method's controls drive it; only the
    noise is shared), so the methods are side by side, one panel each, not overlaid."""
    colors = method_color(run.methods)
    k = len(run.methods)
    fig, axes = new_figure(_WIDTH, _HEIGHT if k == 1 else 1.1 + 2.3 * k, k, 1, sharex=True,
                           sharey=True)
    pf = PlotFigure(f"state-{i}", fig)
    true = {m: run.scalars[f"state/{i}/{m}/true"] for m in run.methods}
    est = {m: run.scalars[f"state/{i}/{m}/estimate"] for m in run.methods}
    ylim, clipped = _limits([v for _, _, v in true.values()],
                            {m: v for m, (_, _, v) in est.items()})
    sym = f"${symbol}_{{{i}}}$"
    for ax, m in zip(axes[:, 0], run.methods):
        _, t, v = true[m]
        (line,) = ax.plot(_seconds(t), v, color=rgb(colors[m]), zorder=2, label=f"{m} true")
        pf.series[f"state/{i}/{m}/true"] = line
        _, t, v = est[m]
        label, style = f"{m} estimate", {"zorder": 3}
        if m in clipped:
            label += f"\n(clipped; it spans {clipped[m][0]:.3g} to {clipped[m][1]:.3g})"
            pf.clipped[f"state/{i}/{m}/estimate"] = clipped[m]
            style = {"zorder": 1, "alpha": 0.6, "lw": 0.6}
        elif np.array_equal(v, true[m][2]):
            label += "\n(= true state, drawn under it)"
            style = {"zorder": 1}
        (line,) = ax.plot(_seconds(t), v, color=estimate_rgb(colors[m]), label=label, **style)
        pf.series[f"state/{i}/{m}/estimate"] = line
        ax.set_ylim(*ylim)
        ax.set_ylabel(axis_label(sym, None))
        ax.margins(x=0.0)
        legend_outside(ax)
    note = ""
    if clipped:
        names = ", ".join(clipped)
        note = (f"y-axis scaled to the true states: the {names} estimate"
                f"{'s are' if len(clipped) > 1 else ' is'} clipped")
    axes[-1, 0].set_xlabel("time t (s)")
    title = _title(run, title.format(sym=sym), note)
    if k == 1:
        axes[0, 0].set_title(title)
    else:
        fig.suptitle(title, fontsize=10)
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
