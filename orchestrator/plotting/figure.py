"""What every figure shares: the :class:`PlotFigure` record, the figure factory (Agg canvas,
fixed size), the deterministic matplotlib settings, colours, labels and legend placement.

matplotlib is used through :class:`matplotlib.figure.Figure` and the Agg canvas only; pyplot
(and its global figure registry and interactive backend) is never imported.
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import matplotlib
import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

__all__ = ["DPI", "LineStyle", "PlotFigure", "axis_label", "deterministic_style",
           "drawing_order", "estimate_rgb", "legend_outside", "line_styles", "new_figure", "rgb"]

#: Resolution of the PNG files, dots per inch; a figure of w x h inches is w*DPI x h*DPI px.
DPI = 150

#: matplotlib settings used while figures are built and saved: a fixed hash salt, so the
#: SVG element ids are the same on every call, paths for text (no font embedding that could
#: vary between hosts), and the same style whatever the user's matplotlibrc says.
_RC = {
    "svg.hashsalt": "auv-cosim",
    "svg.fonttype": "path",
    "pdf.fonttype": 42,
    "path.simplify": True,
    "font.size": 9.0,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "axes.titlesize": 10.0,
    "legend.fontsize": 8.0,
    "lines.linewidth": 1.0,
    "figure.dpi": DPI,
    "savefig.dpi": DPI,
    "savefig.bbox": None,          # keep the stated size: no tight bounding box
}


@contextmanager
def deterministic_style() -> Iterator[None]:
    """Context in which figures are built and saved with the fixed settings of this package
    (matplotlib's defaults, then ``_RC``), whatever the user's matplotlibrc holds."""
    with matplotlib.rc_context():
        matplotlib.rcdefaults()
        matplotlib.rcParams.update(_RC)
        yield


@dataclass(eq=False)
class PlotFigure:
    """One figure, built but not yet saved.

    Attributes
    ----------
    name : str
        File stem, e.g. ``error-1`` (written as ``error-1.png`` etc.).
    figure : matplotlib.figure.Figure
        The figure (Agg canvas).
    series : dict[str, Line2D]
        Recording entity (or ``entity[c]`` for component c, or a derived name such as
        ``vehicles/1/error/kalman:norm``) -> the line that draws it; its data are the values
        read from the .rrd (time in s on x).
    whole : dict[str, Line2D]
        Entity -> the line of its whole-run panel where that panel overlays methods (the bin
        mean of the envelope, or every sample of a short run).
    clipped : dict[str, tuple[float, float]]
        Entity -> (min, max) of a series that leaves the y-axis (drawn clipped, and said so
        in the title and legend).
    """

    name: str
    figure: Figure
    series: dict[str, Line2D] = field(default_factory=dict)
    whole: dict[str, Line2D] = field(default_factory=dict)
    clipped: dict[str, tuple[float, float]] = field(default_factory=dict)


def new_figure(width: float, height: float, nrows: int = 1, ncols: int = 1,
               **subplot_kw: object) -> tuple[Figure, np.ndarray]:
    """A figure of ``width`` x ``height`` inches with a constrained layout and an Agg canvas.

    Parameters
    ----------
    width, height : float
        Size in inches (PNG: times :data:`DPI` pixels).
    nrows, ncols : int, optional
        Grid of axes.
    **subplot_kw
        Passed to :meth:`Figure.subplots` (e.g. ``sharex=True``).

    Returns
    -------
    figure : Figure
    axes : np.ndarray
        Array of Axes of shape (nrows, ncols).
    """
    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False, **subplot_kw)
    return fig, axes


#: matplotlib line width per viewer point of a method's line
_MPL_WIDTH = 1.2


@dataclass(frozen=True)
class LineStyle:
    """A method's line in matplotlib (from :func:`orchestrator.recording.layout.method_styles`,
    the viewer's style): colour, dash, width, opacity and drawing order."""

    color: tuple[float, float, float]
    linestyle: str
    linewidth: float
    alpha: float
    zorder: float

    def kw(self) -> dict[str, object]:
        """The keywords of :meth:`Axes.plot`."""
        return {"color": self.color, "ls": self.linestyle, "lw": self.linewidth,
                "alpha": self.alpha, "zorder": self.zorder}


def line_styles(methods: tuple[str, ...] | list[str], spread: dict[str, float] | None = None,
                base: float = 3.0) -> dict[str, LineStyle]:
    """Each method's :class:`LineStyle`: distinct in colour and in dash or width, and drawn
    back to front by :func:`drawing_order`; z-orders from ``base`` up, below ``base + 1``.

    Parameters
    ----------
    methods : tuple[str, ...] or list[str]
        The methods in the recording's order.
    spread : dict[str, float] or None, optional
        Each method's spread (e.g. the standard deviation of its trace), for the order.
    base : float, optional
        z-order of the back layer.

    Returns
    -------
    dict[str, LineStyle]
    """
    from orchestrator.recording.layout import method_styles
    styles = method_styles(methods)
    order = drawing_order(methods, spread or {}, {m for m, s in styles.items() if s.wide})
    n = max(len(styles), 1)
    return {m: LineStyle(rgb(s.color), s.dash, _MPL_WIDTH * s.width, s.alpha / 255.0,
                         base + order.index(m) / n) for m, s in styles.items()}


def drawing_order(methods: tuple[str, ...] | list[str], spread: dict[str, float],
                  wide: set[str]) -> list[str]:
    """The methods back to front: the widest spread first (its noise would hide the others),
    but each wide translucent method just under the thin method nearest to it in spread
    (the ideal estimator under the Kalman filter, its nearly equal curve), so that the thin
    line shows on top and the wide one round it.

    Parameters
    ----------
    methods : tuple[str, ...] or list[str]
    spread : dict[str, float]
        Spread per method (missing: 0).
    wide : set[str]
        The wide translucent methods.

    Returns
    -------
    list[str]
    """
    def key(m: str) -> float:
        return -spread.get(m, 0.0)
    thin = sorted((m for m in methods if m not in wide), key=key)
    order = list(thin)
    for m in sorted((m for m in methods if m in wide), key=key):
        if not thin:
            order.append(m)
            continue
        partner = min(thin, key=lambda t: abs(spread.get(t, 0.0) - spread.get(m, 0.0)))
        order.insert(order.index(partner), m)
    return order


def rgb(color: tuple[int, int, int] | np.ndarray) -> tuple[float, float, float]:
    """An RGB colour with 0-255 channels as matplotlib's 0-1 floats."""
    r, g, b = (int(c) for c in color[:3])
    return (r / 255.0, g / 255.0, b / 255.0)


def estimate_rgb(color: tuple[int, int, int]) -> tuple[float, float, float]:
    """The colour of a method's estimates: the method colour half-way to white, as in the
    recording (``orchestrator.recording.layout._lighter``)."""
    return rgb(tuple(round(c + (255 - c) * 0.5) for c in color))


def axis_label(quantity: str, unit: str | None) -> str:
    """``"x1 (m)"``, or ``"x1 (model units)"`` when the unit is unknown or empty."""
    return f"{quantity} ({unit})" if unit else f"{quantity} (model units)"


def legend_outside(ax: Axes, ncol: int = 1, handles: list[Artist] | None = None) -> None:
    """The legend of ``ax`` to the right of the axes (outside: it never hides data); the
    constrained layout makes room for it.

    Parameters
    ----------
    ax : Axes
    ncol : int, optional
        Columns of the legend.
    handles : list[Artist] or None, optional
        The entries in this order (default: every labelled artist of ``ax``, drawing order).
    """
    kw = {} if handles is None else {"handles": handles}
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, ncol=ncol,
              frameon=False, handlelength=1.8, **kw)
