"""The distributed observer of the leader, per vehicle (items 1-2 of
:mod:`controller_fmu.distributed`, where the equations are stated in full).

Continuous form eta_i' = F eta_i + mu (sum_j a_ij (eta_j - eta_i) + a_i0 (v - eta_i)),
stacked error I_N kron F - mu (L + G) kron I (eigenvalues f - mu lambda); sampled form with
the innovation r_i[k] held over the step, eta_i[k+1] = Phi eta_i[k] + mu Gam_F r_i[k]
(Phi = expm(F h), Gam_F = int_0^h expm(F t) dt; eigenvalues phi_f - mu lambda gam_f). Also
the neighbour slots of the FMU parameters as a validated graph, and the eigenvalues of
L + G. Units: F in 1/s, mu in 1/s, h in s, the weights dimensionless.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from plant_model.discretization import check_step, zoh
from plant_model.graph import CommunicationGraph, communication_graph
from plant_model.linalg_checks import ModelError, as_matrix, as_vector, fmt_complex

__all__ = [
    "SampledObserver",
    "check_observer_gain",
    "check_sampled_observer",
    "consensus_eigenvalues",
    "graph_from_slots",
    "innovation",
    "min_observer_gain",
    "observer_error_matrix",
    "sampled_observer",
    "sampled_observer_eigenvalues",
    "sampled_observer_gain_range",
]


# ------------------------------------------------------------------------------------
# graph
def graph_from_slots(N: int, neighbours: Any, weights: Any, pinning: Any) -> CommunicationGraph:
    """The communication graph from per-vehicle neighbour slots (the FMU parameters).

    Vehicle i (row i-1) hears vehicle ``neighbours[i-1, k]`` with weight
    ``weights[i-1, k]`` = a_ij for every slot k whose weight is non-zero (unused slots have
    weight 0 and any index); ``pinning[i-1]`` = a_i0 (0: does not hear the leader).

    Parameters
    ----------
    N : int
        Number of vehicles.
    neighbours : Any
        N x S vehicle numbers (1-based), S the number of slots (the largest in-degree).
    weights : Any
        N x S weights a_ij >= 0 (dimensionless).
    pinning : Any
        N pinning weights a_i0 >= 0.

    Returns
    -------
    CommunicationGraph
        The validated graph.

    Raises
    ------
    ModelError
        One line naming the vehicle and slot wired to a vehicle that does not exist, a
        self-loop, a negative weight, or (from :func:`plant_model.graph.communication_graph`)
        the vehicles with no path from the leader.
    """
    nb = np.atleast_2d(np.asarray(neighbours))
    W = as_matrix("neighbour weights", weights)
    if nb.shape != W.shape or nb.shape[0] != N:
        raise ModelError(f"neighbour slots: indices {nb.shape} and weights {W.shape} must both "
                         f"be {N} x S (one row per vehicle)")
    g = as_vector("pinning weights", pinning, N)
    edges = []
    for i in range(1, N + 1):
        for k in range(nb.shape[1]):
            a = float(W[i - 1, k])
            if a < 0.0:
                raise ModelError(f"vehicle {i}: neighbour slot {k + 1} has the negative weight "
                                 f"{a:g}")
            if a == 0.0:
                continue
            j_raw = nb[i - 1, k]
            if not float(j_raw).is_integer() or not 1 <= int(j_raw) <= N:
                raise ModelError(f"vehicle {i}: neighbour slot {k + 1} is wired to vehicle "
                                 f"{j_raw}, which does not exist (vehicles are 1..{N})")
            edges.append((int(j_raw), i, a))
    if np.any(g < 0.0):
        i = int(np.argmax(g < 0.0)) + 1
        raise ModelError(f"vehicle {i}: negative pinning weight {g[i - 1]:g}")
    return communication_graph(N, edges, [(i + 1, float(a)) for i, a in enumerate(g) if a > 0])


def _acyclic(LG: np.ndarray) -> bool:
    """True when the graph of the off-diagonal pattern of LG has no directed cycle."""
    nz = (LG != 0.0) & ~np.eye(LG.shape[0], dtype=bool)
    indeg = nz.sum(axis=1)          # row i: the vehicles i hears
    done = np.zeros(LG.shape[0], dtype=bool)
    while True:
        ready = ~done & (indeg == 0)
        if not ready.any():
            return bool(done.all())
        done |= ready
        indeg = (nz & ~done[None, :]).sum(axis=1)


def consensus_eigenvalues(LG: Any) -> np.ndarray:
    """Eigenvalues lambda of L + G, sorted by real part; all must have Re lambda > 0.

    For an acyclic graph (a tree or any DAG, as every built-in formation) L + G is
    triangular in a topological order and its eigenvalues are exactly its diagonal
    d_i = sum_j a_ij + a_i0; they are read from there, which stays exact when L + G is
    defective (e.g. formation-4: the eigenvalue 1 four times in one Jordan chain), where
    a general eigenvalue solver is off by about eps^(1/k) for a chain of length k.

    Parameters
    ----------
    LG : Any
        L + G, N x N (:meth:`plant_model.graph.CommunicationGraph.consensus_matrix`).

    Returns
    -------
    np.ndarray
        The N eigenvalues (complex), ascending real part.

    Raises
    ------
    ModelError
        If some eigenvalue has Re lambda <= 0 (no spanning tree rooted at the leader).
    """
    LG = as_matrix("L + G", LG)
    lam = (np.diag(LG).astype(complex) if _acyclic(LG)
           else np.linalg.eigvals(LG).astype(complex))
    lam = lam[np.lexsort((lam.imag, lam.real))]
    tol = 1e-12 * max(1.0, float(np.abs(LG).max(initial=0.0)))
    if lam.size and lam[0].real <= tol:
        raise ModelError(f"L + G has the eigenvalue {fmt_complex(lam[0])} with no positive "
                         "real part: "
                         "some vehicle has no directed path from the leader")
    return lam


# ------------------------------------------------------------------------------------
# continuous-time observer
def observer_error_matrix(F: Any, LG: Any, mu: float) -> np.ndarray:
    """I_N kron F - mu (L + G) kron I_l: the continuous observer's stacked error dynamics.

    Parameters
    ----------
    F : Any
        Leader exosystem, l x l, 1/s.
    LG : Any
        L + G, N x N (dimensionless).
    mu : float
        Observer gain, 1/s.

    Returns
    -------
    np.ndarray
        N l x N l, 1/s.
    """
    F = np.asarray(F, dtype=float)
    LG = np.asarray(LG, dtype=float)
    return np.kron(np.eye(LG.shape[0]), F) - mu * np.kron(LG, np.eye(F.shape[0]))


def min_observer_gain(F: Any, LG: Any) -> float:
    """Infimum of the observer gains mu (1/s) for which the continuous observer converges.

    Eigenvalues f - mu lambda need Re f - mu Re lambda < 0 for all pairs, i.e.
    mu > max Re f / min Re lambda. Returns 0.0 when max Re f <= 0: for a marginally stable
    F (every leader path of :mod:`plant_model.leader`) any mu > 0 works; for a Hurwitz F
    even mu = 0 does. The inequality is strict. F and LG as :func:`observer_error_matrix`.

    Returns
    -------
    float
        max(0, max Re f / min Re lambda), 1/s.
    """
    f_max = float(np.max(np.linalg.eigvals(np.asarray(F, dtype=float)).real))
    lam = consensus_eigenvalues(LG)
    return max(0.0, f_max / float(lam[0].real))


def check_observer_gain(F: Any, LG: Any, mu: float) -> float:
    """Refuse an observer gain mu for which the continuous observer does not converge.

    Parameters as :func:`observer_error_matrix`.

    Returns
    -------
    float
        The decay rate max Re(f - mu lambda) < 0 of the observer error, 1/s.

    Raises
    ------
    ModelError
        Naming the eigenvalue lambda of L + G and f of F whose mode does not decay, and
        the smallest gain that works.
    """
    f = np.linalg.eigvals(np.asarray(F, dtype=float))
    worst, where = -np.inf, None
    for lam in consensus_eigenvalues(LG):
        re = f.real - mu * lam.real
        k = int(np.argmax(re))
        if re[k] > worst:
            worst, where = float(re[k]), (lam, f[k])
    if worst >= 0.0:
        lam, fk = where
        raise ModelError(
            f"observer gain mu = {mu:g} 1/s is too small: at eigenvalue {fmt_complex(lam)} of "
            f"L + G the observer mode {fmt_complex(fk - mu * lam)} (eigenvalue "
            f"{fmt_complex(fk)} of F minus mu "
            f"lambda) does not decay; need mu > {min_observer_gain(F, LG):.6g} 1/s")
    return worst


# ------------------------------------------------------------------------------------
# sampled observer
@dataclass(frozen=True)
class SampledObserver:
    """The observer integrated over one communication step h with its innovation held.

    eta_i[k+1] = Phi eta_i[k] + mu Gam_F r_i[k] (module docstring, item 2).
    """

    F: np.ndarray        #: leader exosystem, l x l, 1/s
    h: float             #: communication step, s
    mu: float            #: observer gain, 1/s
    Phi: np.ndarray      #: expm(F h), l x l
    Gam_F: np.ndarray    #: int_0^h expm(F t) dt, l x l, s

    @property
    def B_nbr(self) -> np.ndarray:
        """mu Gam_F (l x l, dimensionless): what the held innovation adds per step."""
        return self.mu * self.Gam_F

    def vehicle_matrices(self, d_i: float) -> tuple[np.ndarray, np.ndarray]:
        """(Ad_i, B_nbr) with eta_i[k+1] = Ad_i eta_i + B_nbr (sum_j a_ij eta_j + a_i0 v).

        Parameters
        ----------
        d_i : float
            sum_j a_ij + a_i0, the vehicle's row sum of L + G.

        Returns
        -------
        Ad_i : np.ndarray
            Phi - mu d_i Gam_F, l x l.
        B_nbr : np.ndarray
            mu Gam_F, l x l.
        """
        return self.Phi - self.mu * d_i * self.Gam_F, self.B_nbr

    def step(self, eta_i: np.ndarray, r_i: np.ndarray) -> np.ndarray:
        """eta_i[k+1] = Phi eta_i[k] + mu Gam_F r_i[k].

        Parameters
        ----------
        eta_i : np.ndarray
            The vehicle's estimate of the leader state at t_k, shape (l,).
        r_i : np.ndarray
            Its innovation at t_k (:func:`innovation`), shape (l,).

        Returns
        -------
        np.ndarray
            eta_i at t_k + h, shape (l,).
        """
        return self.Phi @ eta_i + self.B_nbr @ r_i


def sampled_observer(F: Any, h: float, mu: float) -> SampledObserver:
    """Phi = expm(F h) and Gam_F = int_0^h expm(F t) dt from one exponential (zoh).

    Parameters
    ----------
    F : Any
        Leader exosystem, l x l, 1/s.
    h : float
        Communication step, s.
    mu : float
        Observer gain, 1/s (>= 0).

    Returns
    -------
    SampledObserver
        The per-step matrices.

    Raises
    ------
    ModelError
        If h is not positive or too small for F, or mu is negative or not finite.
    """
    F = as_matrix("leader F", F)
    F = as_matrix("leader F", F, (F.shape[0], F.shape[0]))
    h = float(h)
    if not np.isfinite(h) or h <= 0.0:
        raise ModelError(f"step h = {h} s must be a positive finite number")
    mu = float(mu)
    if not np.isfinite(mu) or mu < 0.0:
        raise ModelError(f"observer gain mu = {mu} 1/s must be a non-negative number")
    check_step(F, h)
    Phi, Gam = zoh(F, np.eye(F.shape[0]), h)
    return SampledObserver(F=F, h=h, mu=mu, Phi=Phi, Gam_F=Gam)


def innovation(eta_i: Any, neighbour_etas: Any, weights: Any, a_i0: float,
               v: Any | None) -> np.ndarray:
    """r_i = sum_j a_ij (eta_j - eta_i) + a_i0 (v - eta_i), in the units of the leader state.

    Parameters
    ----------
    eta_i : Any
        The vehicle's own estimate, shape (l,).
    neighbour_etas : Any
        The neighbours' estimates, shape (S, l) (one row per slot; unused slots weight 0).
    weights : Any
        a_ij per slot, shape (S,).
    a_i0 : float
        Pinning weight (0 when the vehicle does not hear the leader).
    v : Any or None
        The leader's state (ignored, may be None, when a_i0 = 0).

    Returns
    -------
    np.ndarray
        r_i, shape (l,).
    """
    eta_i = np.asarray(eta_i, dtype=float)
    w = np.asarray(weights, dtype=float).reshape(-1)
    r = np.zeros_like(eta_i)
    if w.size:
        E = np.asarray(neighbour_etas, dtype=float).reshape(w.size, -1)
        r = w @ E - w.sum() * eta_i
    if a_i0 != 0.0:
        r = r + a_i0 * (np.asarray(v, dtype=float) - eta_i)
    return r


def _phi1(z: np.ndarray) -> np.ndarray:
    """(exp(z) - 1) / z, 1 at z = 0 (complex)."""
    z = np.asarray(z, dtype=complex)
    small = np.abs(z) < 1e-8
    out = np.ones_like(z)
    out[~small] = np.expm1(z[~small]) / z[~small]
    out[small] = 1.0 + z[small] / 2.0
    return out


def sampled_observer_eigenvalues(F: Any, lam: complex, h: float, mu: float) -> np.ndarray:
    """Eigenvalues phi_f - mu lambda gam_f of the block Phi - mu lambda Gam_F.

    Exact (also for a defective F: the block is an analytic function of F). F, h and mu
    as :func:`sampled_observer`; ``lam`` (complex) an eigenvalue of L + G.

    Returns
    -------
    np.ndarray
        l complex eigenvalues.
    """
    f = np.linalg.eigvals(np.asarray(F, dtype=float)).astype(complex)
    return np.exp(f * h) - mu * lam * h * _phi1(f * h)


def sampled_observer_gain_range(F: Any, LG: Any, h: float) -> tuple[float, float]:
    """The open interval (mu_lo, mu_hi) of gains (1/s) for which the sampled observer converges.

    For each eigenvalue f of F and lambda of L + G, |phi - mu c| < 1 with phi = exp(f h),
    c = lambda gam_f, i.e. |c|^2 mu^2 - 2 mu Re(conj(phi) c) + |phi|^2 - 1 < 0: an interval
    between the two roots; the answer is the intersection (mu_lo >= 0). For a marginally
    stable F, mu_lo = 0 (any small mu > 0 works), and mu_hi is about 2 Re lambda /
    (|lambda|^2 h) for the worst lambda. F and LG as :func:`observer_error_matrix`, the
    communication step h (s) as :func:`sampled_observer`.

    Returns
    -------
    tuple[float, float]
        (mu_lo, mu_hi), 1/s; empty (mu_lo >= mu_hi) when no gain works.
    """
    f = np.linalg.eigvals(np.asarray(F, dtype=float)).astype(complex)
    phi = np.exp(f * h)
    gam = h * _phi1(f * h)
    lo, hi = 0.0, np.inf
    for lam in consensus_eigenvalues(LG):
        c = lam * gam
        a = np.abs(c) ** 2
        b = (np.conj(phi) * c).real
        k = np.abs(phi) ** 2 - 1.0
        for ai, bi, ki in zip(a, b, k):
            if ai == 0.0:
                if ki >= 0.0:
                    return (0.0, 0.0)
                continue
            disc = bi * bi - ai * ki
            if disc <= 0.0:
                return (0.0, 0.0)
            sq = np.sqrt(disc)
            lo = max(lo, (bi - sq) / ai)
            hi = min(hi, (bi + sq) / ai)
    if lo <= 1e-12 * hi:        # |phi| = 1 to rounding: the interval is open at 0
        lo = 0.0
    return (float(lo), float(hi))


def check_sampled_observer(F: Any, LG: Any, h: float, mu: float) -> float:
    """Refuse an observer gain for which the sampled observer does not converge.

    F, LG and mu as :func:`observer_error_matrix`, the communication step h (s) as
    :func:`sampled_observer`.

    Returns
    -------
    float
        The spectral radius (< 1) of the sampled observer error per step.

    Raises
    ------
    ModelError
        Naming the eigenvalue of L + G whose block Phi - mu lambda Gam_F has spectral
        radius >= 1, with the range of gains that works.
    """
    worst, where = -1.0, None
    for lam in consensus_eigenvalues(LG):
        rho = float(np.max(np.abs(sampled_observer_eigenvalues(F, lam, h, mu))))
        if rho > worst:
            worst, where = rho, lam
    if worst >= 1.0:
        lo, hi = sampled_observer_gain_range(F, LG, h)
        ok = (f"gains in ({lo:.6g}, {hi:.6g}) 1/s work" if lo < hi
              else "no gain works at this step")
        raise ModelError(
            f"observer gain mu = {mu:g} 1/s makes the sampled observer unstable at h = {h:g} s: "
            f"at eigenvalue {fmt_complex(where)} of L + G the block expm(F h) - mu lambda "
            f"int_0^h expm(F t) dt has spectral radius {worst:.6g} >= 1; {ok}")
    return worst
