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

__all__ = ["DPI", "PlotFigure", "axis_label", "deterministic_style", "estimate_rgb",
           "legend_outside", "new_figure", "rgb"]

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
    clipped : dict[str, tuple[float, float]]
        Entity -> (min, max) of a series that leaves the y-axis (drawn clipped, and said so
        in the title and legend).
    """

    name: str
    figure: Figure
    series: dict[str, Line2D] = field(default_factory=dict)
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
