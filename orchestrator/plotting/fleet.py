"""Figures of a fleet recording: the formation's paths in the north-east plane and each
vehicle's tracking-error norm against time, one panel per recorded method.

Vehicle colours are those of the viewer's 3D scene
(``orchestrator.recording.layout._vehicle_colors``); the leader is drawn in black.
"""
from __future__ import annotations

import warnings

import numpy as np

from orchestrator.recording import read_rrd_points
from orchestrator.recording.layout import _vehicle_colors

from .figure import PlotFigure, axis_label, legend_outside, new_figure, rgb
from .run_folder import RunData, RunFolderError

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
    return f"{text} — scenario {run.scenario}{seed}{label}"


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
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("east (m)")
        ax.set_ylabel("north (m)")
        ax.set_title(f"method {m}")
    if k > 1:            # the same scale in every panel (before the equal aspect widens it)
        lims = [ax.dataLim for ax in axes[0]]
        corners = [(min(b.x0 for b in lims), min(b.y0 for b in lims)),
                   (max(b.x1 for b in lims), max(b.y1 for b in lims))]
        for ax in axes[0]:
            ax.update_datalim(corners)
            ax.autoscale_view()
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
    colors = [rgb(c) for c in _vehicle_colors(n)]
    k = len(run.methods)
    fig, axes = new_figure(9.0 + (1.0 if n > 10 else 0.0), 0.8 + 3.0 * k, k, 1, sharex=True,
                           sharey=True)
    pf = PlotFigure("fleet-errors", fig)
    names = list(run.error_names)
    units = {run.units.get(c) for c in names} if names else {None}
    unit = units.pop() if len(units) == 1 else None
    for ax, m in zip(axes[:, 0], run.methods):
        for i in range(n):
            entity = f"vehicles/{i + 1}/error/{m}"
            _, t, e = run.scalars[entity]
            norm = np.linalg.norm(np.reshape(e, (len(t), -1)), axis=1)
            (line,) = ax.plot(t.astype(np.float64) / 1e9, norm, color=colors[i],
                              label=f"vehicle {i + 1}")
            pf.series[f"{entity}:norm"] = line
        ax.set_ylabel(axis_label(r"$\|e_i\|$", unit))
        ax.set_title(f"method {m}", loc="left")
        ax.margins(x=0.0)
        ax.set_ylim(bottom=0.0)
    axes[-1, 0].set_xlabel("time t (s)")
    legend_outside(axes[0, 0], ncol=2 if n > 10 else 1)
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
