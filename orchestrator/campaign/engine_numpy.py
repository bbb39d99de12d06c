"""The numpy engine: the paper's closed loop run as one linear recursion, vectorised over seeds.

For a linear plant whose signals reach the estimator and the controller within the step
(the master's Gauss-Seidel coupling: perfect links, no delay), the whole co-simulation is
the sampled closed loop of :func:`orchestrator.analysis.prediction.closed_loop` (the same
matrices the prediction solves its Lyapunov equation with), with X = [s; q] (plant state
s = [x; w; z], estimator state q) and the noise row eta[k] = [v[k]; n[k]; n_z[k]]:

    X[k+1] = Phi X[k] + Gam eta[k],   u[k] = Gx X[k] + Geta eta[k],   e[k] = E s[k],
    X[0] = [s(0); q0]

The noise rows of a seed are the plant FMU's (:class:`plant_model.plant.NoiseStream`, one
PCG64 generator per seed, drawn in blocks of rows), so a seed gives the traces of the FMU
co-simulation to rounding; the statistics are :func:`orchestrator.analysis.summary.trace_stats`.
Seeds are stacked as rows: per step two matrix products for the whole batch
(X Phi' + eta Gam', and the outputs), about 0.3 us per step and seed against about 40 us
for the three FMUs.

Points it does not run (:func:`numpy_unsupported`) go to the FMU engine: the Jacobi
coupling (a delayed loop with its own initial outputs), and scenario sections this engine
does not know (anything but a linear plant with perfect links).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from plant_model.plant import NoiseStream

from ..analysis.prediction import closed_loop
from ..analysis.summary import trace_stats

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["numpy_unsupported", "run_batch", "KNOWN_SECTIONS"]

#: the scenario sections the engine models (a linear plant, perfect links)
KNOWN_SECTIONS = frozenset({"name", "description", "simulation", "vehicles", "disturbance",
                            "reference", "noise", "cost", "leader", "graph", "current"})
#: traces of a batch kept in memory at most (bytes): seeds are run in sub-batches below it
TRACE_BYTES = 256 * 2**20
#: steps per block of noise rows drawn for a sub-batch
BLOCK = 2048


def numpy_unsupported(coupling: str, sections: set[str] | frozenset[str],
                      scenario: Scenario | None = None) -> str | None:
    """Why the numpy engine cannot run a point (None if it can): it covers the stacked loop
    of a linear plant over perfect links, coupled Gauss-Seidel; the FMU kind does not
    matter (it runs no FMU).

    Parameters
    ----------
    coupling : str
        The master's coupling of the point ('gauss-seidel' or 'jacobi').
    sections : set[str]
        The top-level keys of the point's scenario mapping.
    scenario : Scenario, optional
        The point's resolved scenario (its deployment and vehicle models).

    Returns
    -------
    str or None
    """
    if coupling != "gauss-seidel":
        return f"coupling {coupling!r}: the numpy engine runs the exact (Gauss-Seidel) loop only"
    unknown = sorted(set(sections) - KNOWN_SECTIONS)
    if unknown:
        return f"section(s) {', '.join(unknown)}: not a linear plant with perfect links"
    if scenario is not None and scenario.deployment != "stacked":
        return (f"deployment {scenario.deployment!r}: the numpy engine runs the stacked loop "
                "only")
    if scenario is not None and scenario.nonlinear_vehicles:
        return "nonlinear vehicles: the numpy engine runs a linear plant only"
    return None


def run_batch(model: Any, est: Any, Ks: np.ndarray, s0: np.ndarray, Q: np.ndarray,
              R: np.ndarray, seeds: list[int], steps: int, k0: int) -> list[dict[str, Any]]:
    """Statistics of each seed's run of the closed loop (module docstring).

    Parameters
    ----------
    model : DiscreteModel
        The plant sampled at h.
    est : LinearEstimator
        The estimator (its linear form and q0).
    Ks : np.ndarray
        Control gain, u = -Ks est, m x (n + r + l).
    s0 : np.ndarray
        Initial plant state [x0; w0; z0].
    Q, R : np.ndarray
        Cost weights (p x p, m x m).
    seeds : list[int]
        Noise seeds.
    steps : int
        Samples per run.
    k0 : int
        First sample of the statistics window.

    Returns
    -------
    list[dict[str, Any]]
        :func:`trace_stats` of each seed, in the order of ``seeds``.
    """
    Phi, Gam, Gx, Geta = closed_loop(model, est, Ks)
    ns, nX = model.ns, Phi.shape[0]
    p, m = model.E.shape[0], Gx.shape[0]
    # one product per step gives [X[k+1], u[k], e[k]] from [X[k], eta[k]]
    Eb = np.zeros((p, nX))
    Eb[:, :ns] = model.E
    A_X = np.vstack([Phi, Gx, Eb]).T.copy()                       # nX x (nX + m + p)
    A_eta = np.hstack([Gam.T, Geta.T, np.zeros((Gam.shape[1], p))])
    X0 = np.concatenate([s0, est.q0])
    per_seed = max(1, steps * (p + m) * 8)
    batch = max(1, min(len(seeds), TRACE_BYTES // per_seed))
    stats: list[dict[str, Any]] = []
    for b0 in range(0, len(seeds), batch):
        group = seeds[b0:b0 + batch]
        B = len(group)
        streams = [NoiseStream(model, s, block=BLOCK) for s in group]
        e = np.empty((B, steps, p))
        u = np.empty((B, steps, m))
        X = np.tile(X0, (B, 1))
        out = np.empty((B, nX + m + p))
        for c0 in range(0, steps, BLOCK):
            c1 = min(c0 + BLOCK, steps)
            eta = np.stack([st.next_rows(c1 - c0) for st in streams], axis=1)   # (c, B, neta)
            for j, k in enumerate(range(c0, c1)):
                np.matmul(X, A_X, out=out)
                out += eta[j] @ A_eta
                u[:, k] = out[:, nX:nX + m]
                e[:, k] = out[:, nX + m:]
                X = out[:, :nX].copy()
        stats.extend(trace_stats({"e": e[i], "u": u[i]}, Q, R, k0) for i in range(B))
    return stats
