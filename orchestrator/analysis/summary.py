"""Figures of merit from traces, and the summary.json the CLI writes.

Simulated figures are time averages at the sample instants over the window
[t_from, T), where t_from = min(T/2, 5 time constants of the slowest closed-loop mode)
leaves out the start-up transient, so that they estimate the stationary values the
Lyapunov prediction gives:

    rms_e[i] = sqrt(mean_k e_i[k]^2),  rms_u[j] = sqrt(mean_k u_j[k]^2),
    cost_rate = mean_k (e[k]' Q e[k] + u[k]' R u[k])       (J/T, per second)
"""
from __future__ import annotations

import importlib.metadata as md
import math
import platform
from collections.abc import Iterable
from typing import Any

import numpy as np

from plant_model.fixed_order import quadratic_form
from plant_model.noise_factor import NOISE_STREAM

__all__ = ["TraceSums", "trace_stats", "method_summary", "versions", "stats_window",
           "stationary_horizon", "stationarity_note"]


def stats_window(T: float, h: float, settling_time: float) -> int:
    """First sample index of the statistics window.

    k0 = ceil(t_from / h), t_from = min(T / 2, settling_time) (T / 2 if the settling time
    is infinite).

    Parameters
    ----------
    T : float
        Duration of the run, s.
    h : float
        Sampling period, s.
    settling_time : float
        Settling time of the closed loop, s (may be infinite).

    Returns
    -------
    int
        k0.
    """
    t_from = min(T / 2.0, settling_time if math.isfinite(settling_time) else T / 2.0)
    return int(math.ceil(t_from / h - 1e-9))


def stationary_horizon(settling_time: float) -> float:
    """The shortest T whose window [min(T / 2, 5 tau), T) gives stationary figures:
    max(2 * 5 tau, 5 tau + 3 tau) s for the settling time 5 tau (s)."""
    return max(2 * settling_time, settling_time + 3 * settling_time / 5.0)


def stationarity_note(T: float, t0: float, settling_time: float) -> str | None:
    """Why statistics over [t0, T) are not yet stationary figures, or None if they are.

    They are not when the window starts inside the start-up transient (t0 < the settling
    time, 5 time constants tau of the slowest closed-loop mode) or lasts less than 3 tau
    (the time average of a mode with correlation time tau has not converged).

    Parameters
    ----------
    T : float
        End of the run, s.
    t0 : float
        Start of the statistics window, s.
    settling_time : float
        5 tau, s (infinite: nothing settles and nothing is said).

    Returns
    -------
    str or None
        One sentence naming what fails, with the figures.
    """
    if not math.isfinite(settling_time):
        return None
    tau = settling_time / 5.0
    problems = []
    if t0 < settling_time * (1 - 1e-9):
        problems.append(f"it starts at t = {t0:.3g} s, inside the start-up transient (the "
                        f"slowest closed-loop mode settles in 5 tau = {settling_time:.3g} s)")
    if T - t0 < 3 * tau * (1 - 1e-9):
        problems.append(f"it lasts {T - t0:.3g} s, less than 3 correlation times of the "
                        f"slowest mode (3 tau = {3 * tau:.3g} s)")
    if not problems:
        return None
    return ("the statistics window is not stationary yet: " + "; ".join(problems)
            + f"; run at least T = {stationary_horizon(settling_time):.3g} s "
              "for stationary figures (the window starts at min(T / 2, 5 tau)), "
              "or compare with 'predicted_window' (the expected value over this window, "
              "start-up transient included)")


class TraceSums:
    """:func:`trace_stats` accumulated chunk by chunk of window samples (:meth:`add`);
    :meth:`result` gives its dict. One chunk of the whole window gives exactly
    :func:`trace_stats`; more chunks the same figures to rounding.

    Parameters
    ----------
    Q : np.ndarray
        Tracking error weight, p x p.
    R : np.ndarray
        Control weight, m x m.
    """

    def __init__(self, Q: np.ndarray, R: np.ndarray):
        self.Q, self.R = np.asarray(Q, float), np.asarray(R, float)
        self.n = 0                                      #: samples seen
        self.e2 = self.e1 = self.u2 = None              # sums of e^2, e, u^2 per component
        self.cost = 0.0                                 #: sum of e' Q e + u' R u

    def add(self, e: np.ndarray, u: np.ndarray) -> None:
        """Window samples of e (rows, p) and u (rows, m)."""
        # e' Q e per sample over Q's non-zero entries in a fixed order: the same bits on
        # every BLAS kernel (a fleet's Q and R are block diagonal: plant_model.fixed_order)
        cost = quadratic_form(e, self.Q) + quadratic_form(u, self.R)
        parts = (np.sum(e * e, axis=0), np.sum(e, axis=0), np.sum(u * u, axis=0))
        if self.e2 is None:
            self.e2, self.e1, self.u2 = parts
        else:
            self.e2, self.e1, self.u2 = (a + b for a, b in zip((self.e2, self.e1, self.u2),
                                                              parts))
        self.cost += np.sum(cost)
        self.n += e.shape[0]

    def result(self) -> dict[str, Any]:
        """``rms_e``, ``mean_e``, ``rms_u`` (lists) and ``cost_rate`` (float, per second)."""
        n = self.n
        return {"rms_e": np.sqrt(self.e2 / n).tolist(), "mean_e": (self.e1 / n).tolist(),
                "rms_u": np.sqrt(self.u2 / n).tolist(), "cost_rate": float(self.cost / n)}


def trace_stats(traces: dict[str, np.ndarray], Q: np.ndarray, R: np.ndarray,
                k0: int) -> dict[str, Any]:
    """RMS of each e and u component and the cost rate over samples k >= k0.

    rms_e[i] = sqrt(mean_k e_i[k]^2), rms_u[j] = sqrt(mean_k u_j[k]^2),
    cost_rate = mean_k (e[k]' Q e[k] + u[k]' R u[k]).

    Parameters
    ----------
    traces : dict[str, np.ndarray]
        Traces with rows = samples; reads ``e`` (K, p) and ``u`` (K, m).
    Q : np.ndarray
        Tracking error weight, p x p.
    R : np.ndarray
        Control weight, m x m.
    k0 : int
        First sample of the window.

    Returns
    -------
    dict[str, Any]
        ``rms_e``, ``mean_e``, ``rms_u`` (lists) and ``cost_rate`` (float, per second).
    """
    sums = TraceSums(Q, R)
    sums.add(traces["e"][k0:], traces["u"][k0:])
    return sums.result()


def _mean_std(rows: list[list[float]]) -> tuple[list[float], list[float]]:
    a = np.asarray(rows, dtype=float)
    std = a.std(axis=0, ddof=1) if a.shape[0] > 1 else np.zeros(a.shape[1:])
    return a.mean(axis=0).tolist(), np.atleast_1d(std).tolist()


def run_stats(traces: dict[str, np.ndarray], Q: np.ndarray, R: np.ndarray, k0: int,
              formation: tuple | None = None) -> dict[str, Any]:
    """:func:`trace_stats` of one run, with its ``formation`` figures for a fleet.

    Parameters
    ----------
    traces : dict[str, np.ndarray]
        The run's traces.
    Q, R : np.ndarray
        Cost weights.
    k0 : int
        First sample of the statistics window.
    formation : tuple or None, optional
        (position_index, offsets, edges, h) of a fleet
        (:func:`orchestrator.analysis.formation.formation_stats`).

    Returns
    -------
    dict[str, Any]
        The statistics.
    """
    stats = trace_stats(traces, Q, R, k0)
    if formation is not None:
        from .formation import formation_stats
        index, offsets, edges, h = formation
        stats["formation"] = formation_stats(traces["x"], index, offsets, edges, k0, h)
    return stats


def method_summary(per_seed: list[dict[str, Any]], prediction: Any) -> dict[str, Any]:
    """Mean, standard deviation over seeds, and the prediction, as summary.json wants.

    Parameters
    ----------
    per_seed : list[dict[str, Any]]
        :func:`trace_stats` of each seed.
    prediction : Any
        The :class:`~orchestrator.analysis.prediction.Prediction` (or an object with
        ``rms_e``, ``rms_u``, ``cost_rate``, ``reason`` and optionally ``rms_e_mean``).

    Returns
    -------
    dict[str, Any]
        ``rms_e``, ``rms_u``, ``steady_error``, ``cost_rate`` and, when the prediction
        has a reason, ``prediction_note``.
    """
    out: dict[str, Any] = {}
    for key, pred in (("rms_e", prediction.rms_e), ("rms_u", prediction.rms_u)):
        mean, std = _mean_std([s[key] for s in per_seed])
        out[key] = {"mean": mean, "std": std, "predicted": pred}
    mean, std = _mean_std([s["mean_e"] for s in per_seed])
    out["steady_error"] = {
        "time_mean_e": mean,                       #: bias of e over the window (sim)
        "max_abs_time_mean_e": float(np.max(np.abs(mean))),
        "rms_e_without_noise_predicted": getattr(prediction, "rms_e_mean", None),
        "max_rms_e_without_noise_predicted": (
            None if getattr(prediction, "rms_e_mean", None) is None
            else float(np.max(prediction.rms_e_mean))),
    }
    costs = [s["cost_rate"] for s in per_seed]
    out["cost_rate"] = {
        "mean": float(np.mean(costs)),
        "std": float(np.std(costs, ddof=1)) if len(costs) > 1 else 0.0,
        "predicted": prediction.cost_rate,
        "per_seed": costs,
    }
    if prediction.reason:
        out["prediction_note"] = prediction.reason
    return out


def versions(packages: Iterable[str] = ("auv-cosim", "numpy", "scipy", "fmpy", "pythonfmu",
                                         "rerun-sdk")) -> dict[str, str]:
    """Versions of Python and the packages that produced a result.

    Parameters
    ----------
    packages : Iterable[str], optional
        Distribution names to look up.

    Returns
    -------
    dict[str, str]
        ``python``, each package's version ("not installed" if missing) and
        ``noise_stream``, the noise a seed gives (:data:`plant_model.noise_factor.NOISE_STREAM`):
        a campaign's run keys hold these, so rows of two streams are never mixed.
    """
    out = {"python": platform.python_version()}
    for name in packages:
        try:
            out[name] = md.version(name)
        except md.PackageNotFoundError:
            out[name] = "not installed"
    out["noise_stream"] = str(NOISE_STREAM)
    return out
