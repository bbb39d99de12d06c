"""Distributed cooperative output regulation of a fleet, per vehicle (issue 13, `distributed`).

After Su and Huang (IEEE TAC 57(4), 2012, "Cooperative output regulation of linear
multi-agent systems"): every vehicle i = 1..N knows only its own model, its own estimate and
what its neighbours (and, if pinned, the leader) send it. Notation as docs/theory.md
section 8: in-degree Laplacian L, pinning G = diag(a_i0), (L x)_i = sum_j a_ij (x_i - x_j),
d_i = sum_j a_ij + a_i0 the i-th diagonal entry of L + G. Units: time in s, F in 1/s,
the gains a_ij, a_i0 dimensionless, mu in 1/s, the leader state v in the units of the
path (m, m/s for the NED paths).

Vehicle i (continuous time, its own physics only; the consensus is control, not plant)::

    x_i' = A_i x_i + B_i u_i + E_i w_i,   w_i' = K_i w_i   (its own current / disturbance)
    y_i  = C_i x_i,                       target  H v + d_i (formation offset d_i)
    leader (virtual, exosystem)  v' = F v

1. **Distributed observer of the leader** (continuous form)::

       eta_i' = F eta_i + mu (sum_j a_ij (eta_j - eta_i) + a_i0 (v - eta_i))

   The stacked error eta - 1 kron v obeys eta~' = (I_N kron F - mu (L + G) kron I_l) eta~;
   its eigenvalues are exactly f - mu lambda (f of F, lambda of L + G), so it is stable iff
   Re f < mu Re lambda for every pair: mu > max Re f / min Re lambda
   (:func:`min_observer_gain`; any mu > 0 when F is marginally stable, as every leader
   path of :mod:`plant_model.leader` is). Re lambda > 0 for all lambda iff every vehicle
   has a directed path from the leader.

2. **Sampled observer** (what the controller FMU integrates between communication points
   t_k = k h). The innovation of step k is formed from the values received at t_k and held
   over the step, exactly as the plant holds u; the observer's own dynamics F are
   integrated exactly (zero-order hold of the innovation)::

       r_i[k]     = sum_j a_ij (eta_j[k] - eta_i[k]) + a_i0 (v[k] - eta_i[k])
       eta_i[k+1] = Phi eta_i[k] + mu Gam_F r_i[k],   Phi = expm(F h), Gam_F = int_0^h expm(F t) dt
                  = (Phi - mu d_i Gam_F) eta_i[k] + mu Gam_F (sum_j a_ij eta_j[k] + a_i0 v[k])

   A fixed-step co-simulation implements this exactly (two matrix-vector products per step,
   no integration error). The leader's own samples obey v[k+1] = Phi v[k], so eta_i = v is
   an exact fixed point: the sampled observer has *no* steady error on any path. (Holding
   only the neighbour values and integrating the -mu d_i eta_i term continuously, or forward
   Euler, do not have that property: the first lags a moving leader by O(h), forward Euler
   is unstable on an oscillating F for every mu small enough.) Error::

       eta~[k+1] = (I_N kron Phi - mu (L + G) kron Gam_F) eta~[k]

   with eigenvalues phi_f - mu lambda gam_f, phi_f = exp(f h), gam_f = (exp(f h) - 1) / f
   (h when f = 0): stable for mu in an interval (:func:`sampled_observer_gain_range`), which
   also has an upper end (a too large mu makes the sampled observer oscillate).

3. **Local regulator equations**, per vehicle, with its offset as a constant exogenous
   state c (c' = 0, c = 1), the way :mod:`plant_model.fleet` carries the offsets::

       X_i F  = A_i X_i  + B_i U_i,           C_i X_i  = H       (leader, exosystem F)
       Xw_i K_i = A_i Xw_i + B_i Uw_i + E_i,  C_i Xw_i = 0       (own disturbance)
       0      = A_i xc_i + B_i uc_i,          C_i xc_i = d_i     (formation offset)

   solved with :func:`controller_fmu.regulator.solve_regulator_equations` (a transmission
   zero of (A_i, B_i, C_i) at an eigenvalue of F is refused, naming it). For ``remus100``
   X_i = [H; H F] (:func:`plant_model.vehicles.leader_state_map`) and xc_i = [d_i; 0]
   (:func:`plant_model.vehicles.state_offset`): the offset is a state shift at rest with
   uc_i = 0; for other models xc_i is the equilibrium with output d_i (which state_offset's
   least-squares delta need not be). With ``regulator="sampled"`` the same equations are
   solved for the ZOH-sampled vehicle (X Phi = Ad X + Bd U, ...; section 5 of theory.md),
   which makes the tracking error zero *at the samples* for every path; the continuous
   solution leaves an O(h) steady error wherever the feedforward U v(t) varies within a step
   (circles, survey turns) and none on straight lines.

4. **Local LQ gain** Kx_i = R_i^-1 B_i' P_i from the vehicle's own continuous Riccati
   equation A'P + P A - P B R^-1 B' P + C'Q C = 0 (the scenario's [cost] Q in 1/m^2,
   R in 1/N^2), with the stabilizability / detectability checks of
   :func:`controller_fmu.design.lq_riccati_gain`.

5. **The law**, applied to the vehicle's own estimates (xhat_i, what_i) and held over the
   step::

       eps_i = xhat_i - X_i eta_i - Xw_i what_i - xc_i                   (regulation error)
       u_i   = U_i eta_i + Uw_i what_i + uc_i - Kx_i eps_i
               + c Kx_i (sum_j a_ij (eps_j - eps_i) - a_i0 eps_i)          (cohesion, c >= 0)

   The optional cohesion term (c = 0 by default) is the cooperative state feedback of
   Zhang, Lewis and Das (IEEE TAC 56(8), 2011) written on the regulation errors, the
   leader's being 0: it couples the vehicles' deviations from their own steady states and
   vanishes in steady state, so it does not disturb regulation. Neighbours send eps_j
   (state units) besides eta_j. In continuous time, identical vehicles, full information:
   eps' = (I kron (A - B Kx) - c (L + G) kron B Kx) eps, whose blocks A - (1 + c lambda) B Kx
   are Hurwitz for every c >= 0 (the LQ gain margin: Re(1 + c lambda) >= 1/2); sampling
   bounds c from above (:mod:`controller_fmu.distributed_loop`).

The stacked sampled closed loop of all vehicles, its stability verdict per eigenvalue of
L + G and the Lyapunov prediction of the cost rate are in
:mod:`controller_fmu.distributed_loop`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from plant_model.discretization import check_step, zoh
from plant_model.graph import CommunicationGraph, communication_graph
from plant_model.linalg_checks import ModelError, as_matrix, as_vector

from .design import lq_riccati_gain
from .regulator import solve_regulator_equations

__all__ = [
    "REGULATOR_FORMS",
    "SampledObserver",
    "VehicleLaw",
    "check_observer_gain",
    "check_sampled_observer",
    "cohesion_input",
    "consensus_eigenvalues",
    "control_input",
    "design_vehicle_law",
    "graph_from_slots",
    "innovation",
    "min_observer_gain",
    "observer_error_matrix",
    "regulation_error",
    "sampled_observer",
    "sampled_observer_gain_range",
]

#: ``continuous``: the regulator equations of the continuous vehicle (as the stacked
#: ``tracking = "regulator"`` law); ``sampled``: of the ZOH-sampled vehicle (zero error at
#: the samples on every path).
REGULATOR_FORMS = ("continuous", "sampled")


def _fmt(z: complex) -> str:
    z = complex(z)
    return f"{z.real:.6g}" if abs(z.imag) < 1e-12 else f"{z.real:.6g}{z.imag:+.6g}j"


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
        raise ModelError(f"L + G has the eigenvalue {_fmt(lam[0])} with no positive real part: "
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
    even mu = 0 does. The inequality is strict.

    Parameters
    ----------
    F : Any
        Leader exosystem, l x l, 1/s.
    LG : Any
        L + G, N x N.

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

    Parameters
    ----------
    F : Any
        Leader exosystem, l x l, 1/s.
    LG : Any
        L + G, N x N.
    mu : float
        Observer gain, 1/s.

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
            f"observer gain mu = {mu:g} 1/s is too small: at eigenvalue {_fmt(lam)} of L + G "
            f"the observer mode {_fmt(fk - mu * lam)} (eigenvalue {_fmt(fk)} of F minus mu "
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

    Exact (also for a defective F: the block is an analytic function of F).

    Parameters
    ----------
    F : Any
        Leader exosystem, l x l, 1/s.
    lam : complex
        An eigenvalue of L + G.
    h : float
        Communication step, s.
    mu : float
        Observer gain, 1/s.

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
    (|lambda|^2 h) for the worst lambda.

    Parameters
    ----------
    F : Any
        Leader exosystem, l x l, 1/s.
    LG : Any
        L + G, N x N.
    h : float
        Communication step, s.

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
    return (float(lo), float(hi))


def check_sampled_observer(F: Any, LG: Any, h: float, mu: float) -> float:
    """Refuse an observer gain for which the sampled observer does not converge.

    Parameters
    ----------
    F : Any
        Leader exosystem, l x l, 1/s.
    LG : Any
        L + G, N x N.
    h : float
        Communication step, s.
    mu : float
        Observer gain, 1/s.

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
            f"at eigenvalue {_fmt(where)} of L + G the block expm(F h) - mu lambda "
            f"int_0^h expm(F t) dt has spectral radius {worst:.6g} >= 1; {ok}")
    return worst


# ------------------------------------------------------------------------------------
# per-vehicle law
@dataclass(frozen=True)
class VehicleLaw:
    """One vehicle's regulator solution and LQ gain (module docstring, items 3-5).

    u = U eta + Uw what + uc - Kx (xhat - X eta - Xw what - xc) (+ cohesion).
    Gains map state units to input units (N per m and per m/s for ``remus100``).
    """

    Kx: np.ndarray       #: LQ gain R^-1 B' P, m x p
    P: np.ndarray        #: Riccati solution, p x p
    poles: np.ndarray    #: eigenvalues of A - B Kx, 1/s
    X: np.ndarray        #: leader -> steady state, p x l
    U: np.ndarray        #: leader -> steady input, m x l
    Xw: np.ndarray       #: own disturbance -> steady state, p x r
    Uw: np.ndarray       #: own disturbance -> steady input, m x r
    xc: np.ndarray       #: formation offset as a state, (p,)
    uc: np.ndarray       #: input holding the offset, (m,)
    regulator: str       #: one of REGULATOR_FORMS
    h: float | None      #: the step the sampled regulator was solved for

    @property
    def gain_eta(self) -> np.ndarray:
        """U + Kx X (m x l): u = -Kx xhat + gain_eta eta + gain_what what + u0."""
        return self.U + self.Kx @ self.X

    @property
    def gain_what(self) -> np.ndarray:
        """Uw + Kx Xw, m x r."""
        return self.Uw + self.Kx @ self.Xw

    @property
    def u0(self) -> np.ndarray:
        """uc + Kx xc, (m,)."""
        return self.uc + self.Kx @ self.xc


def _sampled_vehicle(A: np.ndarray, B: np.ndarray, E: np.ndarray, Kw: np.ndarray,
                     h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(Ad, Adw, Bd, Phi_w) of the ZOH-sampled [x; w]: x+ = Ad x + Adw w + Bd u, w+ = Phi_w w."""
    p, r = A.shape[0], Kw.shape[0]
    Ac = np.zeros((p + r, p + r))
    Ac[:p, :p], Ac[:p, p:], Ac[p:, p:] = A, E, Kw
    Bc = np.vstack([B, np.zeros((r, B.shape[1]))])
    check_step(Ac, h)
    Ad, Bd = zoh(Ac, Bc, h)
    return Ad[:p, :p], Ad[:p, p:], Bd[:p], Ad[p:, p:]


def _solve(A: np.ndarray, B: np.ndarray, C: np.ndarray, S: np.ndarray, Pv: np.ndarray,
           Hv: np.ndarray, exo: str, where: str, f_eigs: np.ndarray | None,
           h: float | None) -> tuple[np.ndarray, np.ndarray]:
    """solve_regulator_equations, its message prefixed; sampled: name the eigenvalue of F."""
    try:
        return solve_regulator_equations(A, B, C, S, Pv, Hv, exosystem=exo)
    except ModelError as exc:
        if f_eigs is None or h is None:
            raise ModelError(f"{where}{exc}") from None
        # delta form: the eigenvalue (exp(f h) - 1)/h of S failed; find f
        n, m = B.shape
        worst, fk = np.inf, f_eigs[0]
        for f in f_eigs:
            dl = (np.exp(f * h) - 1.0) / h if f != 0 else 0.0
            M = np.zeros((n + C.shape[0], n + m), dtype=complex)
            M[:n, :n], M[:n, n:], M[n:, :n] = A - dl * np.eye(n), B, C
            s = np.linalg.svd(M, compute_uv=False)[-1]
            if s < worst:
                worst, fk = s, f
        raise ModelError(
            f"{where}the sampled regulator equations have no solution: at eigenvalue "
            f"{_fmt(fk)} of the leader's F (exp(f h) = {_fmt(np.exp(fk * h))}) the vehicle "
            f"sampled at h = {h:g} s has a transmission zero ({exc})") from None


def design_vehicle_law(A: Any, B: Any, C: Any, Q: Any, R: Any, F: Any, H: Any,
                       offset: Any | None = None, E: Any | None = None, Kw: Any | None = None,
                       *, regulator: str = "continuous", h: float | None = None,
                       where: str = "") -> VehicleLaw:
    """One vehicle's local design: regulator equations (with its offset) and LQ gain.

    Continuous form (module docstring, item 3)::

        X F = A X + B U,  C X = H;   Xw Kw = A Xw + B Uw + E,  C Xw = 0;
        0 = A xc + B uc,  C xc = d

    ``regulator="sampled"``: the same for the ZOH-sampled vehicle x+ = Ad x + Adw w + Bd u
    (X Phi = Ad X + Bd U, Xw Phi_w = Ad Xw + Bd Uw + Adw, xc = Ad xc + Bd uc), solved in the
    delta form ((Ad - I)/h, Bd/h, (Phi - I)/h) so that it tends to the continuous one as
    h -> 0. Kx = R^-1 B' P from A'P + P A - P B R^-1 B' P + C'Q C = 0 in both cases.

    Parameters
    ----------
    A, B, C : Any
        Vehicle model: p x p (1/s), p x m, s x p.
    Q, R : Any
        Cost weights on the output error (s x s, 1/m^2) and the input (m x m, 1/N^2).
    F, H : Any
        Leader exosystem (l x l, 1/s) and its tracked output (s x l).
    offset : Any or None, optional
        Formation offset d_i (s,), in output units (m); default 0.
    E, Kw : Any or None, optional
        Disturbance input (p x r) and the disturbance's own exosystem (r x r, 1/s); default
        none (r = 0).
    regulator : str, optional
        One of :data:`REGULATOR_FORMS`.
    h : float or None, optional
        Communication step (s); required for ``regulator="sampled"``.
    where : str, optional
        Prefix of the error messages, e.g. "vehicle 3: ".

    Returns
    -------
    VehicleLaw
        X, U, Xw, Uw, xc, uc, Kx, P, the continuous closed-loop poles.

    Raises
    ------
    ModelError
        One line: (A, B) not stabilizable or (C, A) not detectable (naming the modes), or the
        regulator equations unsolvable (naming the eigenvalue of F, K or 0 where a
        transmission zero sits).
    """
    A = as_matrix(f"{where}A", A)
    p = A.shape[0]
    A = as_matrix(f"{where}A", A, (p, p))
    B = as_matrix(f"{where}B", B, (p, None))
    C = as_matrix(f"{where}C", C, (None, p))
    m, s = B.shape[1], C.shape[0]
    Q = as_matrix(f"{where}Q", Q, (s, s))
    R = as_matrix(f"{where}R", R, (m, m))
    F = as_matrix("leader F", F)
    l_ = F.shape[0]
    F = as_matrix("leader F", F, (l_, l_))
    H = as_matrix("leader H", H, (s, l_))
    d = np.zeros(s) if offset is None else as_vector(f"{where}formation offset", offset, s)
    E = np.zeros((p, 0)) if E is None else as_matrix(f"{where}E", E, (p, None))
    r = E.shape[1]
    Kw = np.zeros((r, r)) if Kw is None else as_matrix(f"{where}disturbance K", Kw, (r, r))
    if regulator not in REGULATOR_FORMS:
        raise ModelError(f"unknown regulator form {regulator!r}; expected one of "
                         f"{', '.join(REGULATOR_FORMS)}")
    P, Kx, poles, _ = lq_riccati_gain(A, B, C, Q, R, where=where)
    zero = np.zeros((1, 1))
    # the continuous equations always: a transmission zero of the vehicle at an eigenvalue
    # of F is named here (the sampled vehicle's zeros are only near exp(zero h), so the
    # sampled equations would be solvable but ill-conditioned)
    X, U = _solve(A, B, C, F, np.zeros((p, l_)), H, "F (leader)", where, None, None)
    Xw, Uw = _solve(A, B, C, Kw, E, np.zeros((s, r)), "K (own disturbance)", where,
                    None, None)
    xc, uc = _solve(A, B, C, zero, np.zeros((p, 1)), d[:, None], "0 (formation offset)",
                    where, None, None)
    h_used = None
    if regulator == "sampled":
        if h is None or not np.isfinite(float(h)) or float(h) <= 0.0:
            raise ModelError(f"the sampled regulator needs a positive step h, got {h!r}")
        h_used = float(h)
        Ad, Adw, Bd, Phi_w = _sampled_vehicle(A, B, E, Kw, h_used)
        check_step(F, h_used)
        Phi, _ = zoh(F, np.zeros((l_, 0)), h_used)
        Ah, Bh = (Ad - np.eye(p)) / h_used, Bd / h_used
        X, U = _solve(Ah, Bh, C, (Phi - np.eye(l_)) / h_used, np.zeros((p, l_)), H,
                      "(expm(F h) - I)/h (sampled leader)", where,
                      np.linalg.eigvals(F), h_used)
        Xw, Uw = _solve(Ah, Bh, C, (Phi_w - np.eye(r)) / h_used, Adw / h_used,
                        np.zeros((s, r)), "(expm(K h) - I)/h (own disturbance, sampled)",
                        where, None, None)
        xc, uc = _solve(Ah, Bh, C, zero, np.zeros((p, 1)), d[:, None],
                        "0 (formation offset)", where, None, None)
    return VehicleLaw(Kx=Kx, P=P, poles=poles, X=X, U=U, Xw=Xw, Uw=Uw, xc=xc[:, 0],
                      uc=uc[:, 0], regulator=regulator, h=h_used)


def regulation_error(law: VehicleLaw, xhat: Any, what: Any | None, eta: Any) -> np.ndarray:
    """eps_i = xhat_i - X eta_i - Xw what_i - xc (state units): the deviation from the
    vehicle's own steady state; what is sent to neighbours for the cohesion term.

    Parameters
    ----------
    law : VehicleLaw
        The vehicle's design.
    xhat : Any
        State estimate, (p,).
    what : Any or None
        Disturbance estimate, (r,) (None when r = 0).
    eta : Any
        The vehicle's estimate of the leader state, (l,).

    Returns
    -------
    np.ndarray
        eps_i, (p,).
    """
    eps = np.asarray(xhat, dtype=float) - law.X @ np.asarray(eta, dtype=float) - law.xc
    if law.Xw.shape[1]:
        eps = eps - law.Xw @ np.asarray(what, dtype=float)
    return eps


def cohesion_input(law: VehicleLaw, c: float, eps_i: Any, neighbour_eps: Any,
                   weights: Any, a_i0: float) -> np.ndarray:
    """c Kx (sum_j a_ij (eps_j - eps_i) - a_i0 eps_i): the cooperative (cohesion) force.

    Parameters
    ----------
    law : VehicleLaw
        The vehicle's design (its Kx is the cohesion gain's direction).
    c : float
        Coupling gain (dimensionless, >= 0; 0 switches the term off).
    eps_i : Any
        The vehicle's own regulation error, (p,).
    neighbour_eps : Any
        The neighbours' regulation errors, (S, p).
    weights : Any
        a_ij per slot, (S,).
    a_i0 : float
        Pinning weight.

    Returns
    -------
    np.ndarray
        The force, (m,) (N for ``remus100``).
    """
    if c == 0.0:
        return np.zeros(law.Kx.shape[0])
    eps_i = np.asarray(eps_i, dtype=float)
    # same form as the observer's innovation, with the leader's regulation error 0
    rel = innovation(eps_i, neighbour_eps, weights, a_i0, np.zeros_like(eps_i))
    return c * (law.Kx @ rel)


def control_input(law: VehicleLaw, xhat: Any, what: Any | None, eta: Any,
                  cohesion: Any | None = None) -> np.ndarray:
    """u_i = U eta + Uw what + uc - Kx eps_i (+ cohesion), held over the step.

    Parameters
    ----------
    law : VehicleLaw
        The vehicle's design.
    xhat : Any
        State estimate, (p,).
    what : Any or None
        Disturbance estimate, (r,) (None when r = 0).
    eta : Any
        The vehicle's estimate of the leader state, (l,).
    cohesion : Any or None, optional
        The term of :func:`cohesion_input`, (m,).

    Returns
    -------
    np.ndarray
        u_i, (m,) (N for ``remus100``).
    """
    eta = np.asarray(eta, dtype=float)
    eps = regulation_error(law, xhat, what, eta)
    u = law.U @ eta + law.uc - law.Kx @ eps
    if law.Uw.shape[1]:
        u = u + law.Uw @ np.asarray(what, dtype=float)
    if cohesion is not None:
        u = u + np.asarray(cohesion, dtype=float)
    return u
