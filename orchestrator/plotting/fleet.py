"""Figures of a fleet recording: the formation's paths in the north-east plane and each
vehicle's tracking-error norm against time, one panel per recorded method.

Vehicle colours are those of the viewer's 3D scene
(``orchestrator.recording.layout._vehicle_colors``); the leader is drawn in black.
"""
from __future__ import annotations

import warnings

import numpy as np
from matplotlib.figure import Figure

from orchestrator.recording import read_rrd_points
from orchestrator.recording.layout import _vehicle_colors

from .figure import PlotFigure, axis_label, new_figure, rgb
from .run_folder import RunData, RunFolderError
from .window import finite_limits, stats_start

__all__ = ["fleet_figures"]

_LEADER = (0.0, 0.0, 0.0)
_PANEL = 5.2           # inches per path panel


def _points(run: RunData, entity: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(time s, positions (rows, n, 3) m) of a Points3D entity, or None if not recorded."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _, t, pos = read_rrd_points(run.rrd, entity)
    except KeyError:
        return None
    except (RuntimeError, ValueError, OSError) as exc:
        raise RunFolderError(f"{run.rrd}: {entity} cannot be read: "
                             f"{str(exc).splitlines()[0] if str(exc) else exc}") from None
    return t.astype(np.float64) / 1e9, pos


def _title(run: RunData, text: str) -> str:
    seed = "" if run.seed is None else f", seed {run.seed}"
    label = f"\n{run.label}" if run.label else ""
    return f"{text}\nscenario {run.scenario}{seed}{label}"


#: margin around the paths, a fraction of the larger extent
_PATH_MARGIN = 0.04
#: the paths are drawn to scale (equal aspect) when north and east extents differ by at most
#: this factor; beyond it the panel takes a bounded shape and says it is not to scale
_MAX_ASPECT = 3.0
#: a tall panel is at most this many times :data:`_PANEL` high
_TALL = 1.5
#: the narrowest figure, inches (room for its title)
_MIN_WIDTH = 7.5


def path_limits(lines: list, margin: float = _PATH_MARGIN) -> tuple[tuple[float, float],
                                                                    tuple[float, float]]:
    """(x-limits, y-limits) framing the finite data of ``lines`` with a margin of
    ``margin`` times the larger extent on every side.

    Parameters
    ----------
    lines : list[Line2D]
        The drawn paths (and markers).
    margin : float, optional

    Returns
    -------
    tuple[tuple[float, float], tuple[float, float]]
    """
    xs = np.concatenate([np.asarray(ln.get_xdata(), float).ravel() for ln in lines])
    ys = np.concatenate([np.asarray(ln.get_ydata(), float).ravel() for ln in lines])
    ok = np.isfinite(xs) & np.isfinite(ys)
    if not ok.any():
        return (-1.0, 1.0), (-1.0, 1.0)
    x0, x1, y0, y1 = xs[ok].min(), xs[ok].max(), ys[ok].min(), ys[ok].max()
    pad = margin * max(x1 - x0, y1 - y0, 1.0)
    return (float(x0 - pad), float(x1 + pad)), (float(y0 - pad), float(y1 + pad))


def _frame_on_data(fig: Figure, axes: np.ndarray, lines: list, extra: float) -> None:
    """Every path panel framed on the data (the same limits in each): to scale when the
    extents are within :data:`_MAX_ASPECT` of each other (the panel takes the data's
    shape, nothing left empty), else stretched to a bounded shape, said in the panel. The
    figure is sized to the panels, ``extra`` inches wider for the legend."""
    (x0, x1), (y0, y1) = path_limits(lines)
    ratio = (y1 - y0) / (x1 - x0)
    for ax in axes:
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        if 1 / _MAX_ASPECT <= ratio <= _MAX_ASPECT:
            ax.set_box_aspect(ratio)
        else:
            ax.set_box_aspect(min(max(ratio, 1 / _MAX_ASPECT), _MAX_ASPECT))
            ax.text(0.01, 0.01, "not to scale (north and east stretched differently)",
                    transform=ax.transAxes, fontsize=7, color="0.35", va="bottom")
    box = min(max(ratio, 1 / _MAX_ASPECT), _MAX_ASPECT)     # height / width of a panel
    panel_w = _PANEL if box <= 1 else max(_PANEL / box, _PANEL * _TALL / box)
    panel_h = min(panel_w * box, _PANEL * _TALL)
    fig.set_size_inches(max(len(axes) * panel_w + extra, _MIN_WIDTH), panel_h + 1.1)


def _paths_figure(run: RunData, n: int) -> PlotFigure:
    colors = [rgb(c) for c in _vehicle_colors(n)]
    k = len(run.methods)
    fig, axes = new_figure(_PANEL * k + 1.8 + (1.0 if n > 10 else 0.0), _PANEL + 0.6, 1, k)
    pf = PlotFigure("fleet-paths", fig)
    for ax, m in zip(axes[0], run.methods):
        vehicles = _points(run, f"world/{m}/vehicles")
        if vehicles is None:
            raise RunFolderError(f"{run.rrd} has no vehicle positions (world/{m}/vehicles): "
                                 "not a fleet recording of auv-cosim?")
        _, pos = vehicles
        leader = _points(run, f"world/{m}/leader")
        targets = _points(run, f"world/{m}/targets")
        if leader is not None:
            lp = leader[1][:, 0, :].astype(np.float64)
            (line,) = ax.plot(lp[:, 1], lp[:, 0], color=_LEADER, lw=1.4, ls="--",
                              label="leader", zorder=3)
            pf.series[f"world/{m}/leader"] = line
            ax.plot(lp[0, 1], lp[0, 0], "o", mfc="none", mec=_LEADER, ms=6, zorder=4)
            ax.plot(lp[-1, 1], lp[-1, 0], "o", color=_LEADER, ms=6, zorder=4)
        for i in range(n):
            p = pos[:, i, :].astype(np.float64)
            (line,) = ax.plot(p[:, 1], p[:, 0], color=colors[i], label=f"vehicle {i + 1}",
                              zorder=2)
            pf.series[f"world/{m}/vehicles[{i}]"] = line
            ax.plot(p[0, 1], p[0, 0], "o", mfc="none", mec=colors[i], ms=5, zorder=4)
            ax.plot(p[-1, 1], p[-1, 0], "o", color=colors[i], ms=5, zorder=4)
        if targets is not None:
            tp = targets[1][-1].astype(np.float64)          # (n, 3) at the last sample
            (line,) = ax.plot(tp[:, 1], tp[:, 0], "x", color="0.25", ms=7, mew=1.5,
                              zorder=5, label="_targets")
            pf.series[f"world/{m}/targets[-1]"] = line
        ax.set_xlabel("east (m)")
        ax.set_ylabel("north (m)")
        ax.set_title(f"method {m}")
    _frame_on_data(fig, axes[0], list(pf.series.values()),
                   1.8 + (1.0 if n > 10 else 0.0))
    last = axes[0, -1]
    # marker key: start (open), end (filled), formation target at the end (x)
    last.plot([], [], "o", mfc="none", mec="0.3", ls="none", label="start")
    last.plot([], [], "o", color="0.3", ls="none", label="end")
    if any(k.endswith("targets[-1]") for k in pf.series):
        last.plot([], [], "x", color="0.25", mew=1.5, ls="none", label="target at end")
    handles, labels = last.get_legend_handles_labels()
    keep = [(h, lb) for h, lb in zip(handles, labels) if not lb.startswith("_")]
    last.legend([h for h, _ in keep], [lb for _, lb in keep], loc="upper left",
                bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, frameon=False,
                ncol=2 if n > 10 else 1)
    fig.suptitle(_title(run, f"Formation paths of {n} vehicles (north-east plane, seen from "
                             "above)"), fontsize=10)
    return pf


def _error_norm_figure(run: RunData, n: int) -> PlotFigure:
    """fleet-errors: per method a row, the whole run with the start-up transient shaded (up
    to the start of the statistics window) and a zoom on the statistics window, its y-axis
    scaled to the window. The methods' rows share their y-axes column by column (one scale
    for the whole runs, one for the windows), so the gap between the methods shows."""
    colors = [rgb(c) for c in _vehicle_colors(n)]
    k = len(run.methods)
    fig, axes = new_figure(11.5 + (1.0 if n > 10 else 0.0), 0.9 + 3.0 * k, k, 2,
                           sharex="col", sharey="col",
                           gridspec_kw={"width_ratios": [1.4, 1.0]})
    pf = PlotFigure("fleet-errors", fig)
    names = list(run.error_names)
    units = {run.units.get(c) for c in names} if names else {None}
    unit = units.pop() if len(units) == 1 else None
    windows = []
    for (whole, zoom), m in zip(axes, run.methods):
        drawn = []
        for i in range(n):
            entity = f"vehicles/{i + 1}/error/{m}"
            _, t, e = run.scalars[entity]
            ts = t.astype(np.float64) / 1e9
            norm = np.linalg.norm(np.reshape(e, (len(t), -1)), axis=1)
            (line,) = whole.plot(ts, norm, color=colors[i], label=f"vehicle {i + 1}")
            pf.series[f"{entity}:norm"] = line
            zoom.plot(ts, norm, color=colors[i])
            drawn.append((ts, norm))
        t_end = max(float(ts[-1]) for ts, _ in drawn if len(ts))
        t0 = stats_start(run.summary, t_end)
        if t0 > 0:
            whole.axvspan(0.0, t0, color="0.85", lw=0, zorder=0,
                          label="start-up transient\n(before the statistics window)")
        whole.set_xlim(0.0, t_end)
        zoom.set_xlim(t0, t_end)
        windows.append((drawn, t0, t_end))
        whole.set_ylabel(axis_label(r"$\|e_i\|$", unit))
        whole.set_title(f"method {m}: whole run", loc="left")
        t1 = (run.summary.get("stats_window_s") or [None, t_end])[1] or t_end
        zoom.set_title(f"statistics window t in [{t0:.4g}, {t1:.4g}) s", loc="left")
    for ax in axes[-1]:
        ax.set_xlabel("time t (s)")
    axes[0, 0].set_ylim(bottom=0.0)      # shared by the column: every method's whole run
    lims = [lim for drawn, t0, t1 in windows if (lim := finite_limits(drawn, t0, t1))]
    if lims:                             # one scale for every method's window
        axes[0, 1].set_ylim(0.0, max(hi for _, hi in lims))
    handles, labels = axes[0, 0].get_legend_handles_labels()
    axes[0, 1].legend(handles, labels, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                      borderaxespad=0.0, ncol=2 if n > 10 else 1, frameon=False)
    comps = ", ".join(names) if names else "all components"
    fig.suptitle(_title(run, f"Tracking-error norm of each vehicle, $\\|e_i\\|$ over {comps}"),
                 fontsize=10)
    return pf


def fleet_figures(run: RunData) -> list[PlotFigure]:
    """The fleet figures of a fleet recording.

    Parameters
    ----------
    run : RunData
        A run folder whose recording is in the fleet layout.

    Returns
    -------
    list[PlotFigure]
        ``fleet-paths`` (leader and vehicle paths in the north-east plane, start and end
        marked, the formation targets at the end) and ``fleet-errors`` (the norm of each
        vehicle's tracking error against time), one panel per method.
    """
    n = run.n_vehicles()
    return [_paths_figure(run, n), _error_norm_figure(run, n)]
