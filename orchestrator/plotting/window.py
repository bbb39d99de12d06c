"""What makes a long noisy trace readable: the envelope of the noise over the whole run
(minimum and maximum per time bin, with the bin mean) and a zoomed window after the
start-up transient, where each sample is drawn.

The statistics window of a run (``stats_window_s`` of its summary.json, the one window all
methods of a compare share) starts after the start-up transient; the zoom starts there.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from matplotlib.axes import Axes
from matplotlib.lines import Line2D

__all__ = ["BINS", "ZOOM_S", "Envelope", "draw_envelope", "envelope", "finite_limits",
           "stats_start", "zoom_window"]

#: time bins of the whole-run envelope (a run with fewer than 2 samples a bin is drawn
#: sample by sample)
BINS = 400
#: length of the zoomed window, s
ZOOM_S = 20.0


class Envelope(NamedTuple):
    """Per time bin: centre time (s), minimum, maximum and mean of the finite samples."""

    t: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    mean: np.ndarray


def envelope(t: np.ndarray, v: np.ndarray, bins: int = BINS) -> Envelope:
    """The minimum, maximum and mean of ``v`` in ``bins`` equal runs of samples.

    Parameters
    ----------
    t, v : np.ndarray
        Time (s) and values, one per sample.
    bins : int, optional
        Number of bins (at most one per sample).

    Returns
    -------
    Envelope
        Non-finite samples (a diverged run) are left out of each bin; a bin with none
        finite is NaN.
    """
    t = np.asarray(t, float)
    v = np.asarray(v, float)
    bins = max(1, min(bins, len(v)))
    edges = np.linspace(0, len(v), bins + 1).astype(int)
    out = np.full((4, bins), np.nan)
    for b, (a, z) in enumerate(zip(edges[:-1], edges[1:])):
        seg = v[a:z]
        out[0, b] = 0.5 * (t[a] + t[z - 1])
        seg = seg[np.isfinite(seg)]
        if seg.size:
            out[1:, b] = seg.min(), seg.max(), seg.mean()
    return Envelope(*out)


def draw_envelope(ax: Axes, t: np.ndarray, v: np.ndarray, color: tuple[float, float, float],
                  *, zorder: float = 2.0, label: str | None = None,
                  line: dict[str, object] | None = None,
                  band_zorder: float | None = None) -> Line2D:
    """The whole run of ``v`` on ``ax``: its min-max band per bin (light) and the bin mean
    (a line), or every sample when the run is short (fewer than 2 samples a bin).

    ``line`` (keywords of :meth:`Axes.plot`: a method's :class:`~.figure.LineStyle`) styles
    the line instead of ``color`` and ``zorder``; ``band_zorder`` puts the band elsewhere
    (under every method's line). Returns the line."""
    style = {"color": color, "zorder": zorder, **(line or {})}
    if len(v) < 2 * BINS:
        style.setdefault("lw", 0.8)
        (drawn,) = ax.plot(t, v, label=label, **style)
        return drawn
    env = envelope(t, v)
    ax.fill_between(env.t, env.lo, env.hi, color=style["color"], alpha=0.22, lw=0,
                    zorder=zorder if band_zorder is None else band_zorder)
    style.setdefault("lw", 1.1)
    if line is None:
        style["zorder"] = zorder + 0.05
    (drawn,) = ax.plot(env.t, env.mean, label=label, **style)
    return drawn


def stats_start(summary: dict, t_end: float) -> float:
    """Start of the statistics window, s (the end of the start-up transient), from the
    summary; 0 when the summary does not say."""
    window = summary.get("stats_window_s")
    if isinstance(window, (list, tuple)) and window and window[0] is not None:
        return float(min(max(window[0], 0.0), t_end))
    return 0.0


def zoom_window(summary: dict, t_end: float, length: float = ZOOM_S) -> tuple[float, float]:
    """The zoomed window: ``length`` s from the start of the statistics window (the last
    ``length`` s when less is left), within [0, T] (T: the summary's, else ``t_end``, the
    last sample's time)."""
    if isinstance(summary.get("T"), (int, float)):
        t_end = max(t_end, float(summary["T"]))
    t0 = stats_start(summary, t_end)
    if np.ceil(t0) + length <= t_end:        # a whole second: round tick labels
        t0 = float(np.ceil(t0))
    if t_end - t0 < length:
        t0 = max(0.0, t_end - length)
    return t0, min(t_end, t0 + length)


def finite_limits(series: list[tuple[np.ndarray, np.ndarray]], t0: float, t1: float,
                  margin: float = 0.06) -> tuple[float, float] | None:
    """y-limits of the finite values of (t, v) series within t0 <= t <= t1, with a margin;
    None when there is none."""
    vals = [v[(t >= t0) & (t <= t1)] for t, v in series]
    vals = [x[np.isfinite(x)] for x in vals]
    vals = [x for x in vals if x.size]
    if not vals:
        return None
    lo, hi = min(float(x.min()) for x in vals), max(float(x.max()) for x in vals)
    pad = margin * (hi - lo if hi > lo else max(abs(hi), 1.0))
    return lo - pad, hi + pad
