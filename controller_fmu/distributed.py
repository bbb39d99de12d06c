"""Distributed cooperative output regulation of a fleet, per vehicle.

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
   X_i = [H; H F] (:func:`plant_model.vehicle_targets.leader_state_map`) and xc_i = [d_i; 0]
   (:func:`plant_model.vehicle_targets.state_offset`): the offset is a state shift at rest with
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
   bounds c from above (:mod:`orchestrator.analysis.distributed`).

Items 1-2 are in :mod:`controller_fmu.distributed_observer` (re-exported here), items 3-5
below. The stacked sampled closed loop of all vehicles, its stability verdict per eigenvalue of
L + G and the Lyapunov prediction of the cost rate are in
:mod:`orchestrator.analysis.distributed` (its verdict in
:mod:`orchestrator.analysis.distributed_verdict`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from plant_model.discretization import check_step, zoh
from plant_model.linalg_checks import ModelError, as_matrix, as_square, as_vector, fmt_complex

from .design import lq_riccati_gain
from .distributed_observer import (
    SampledObserver,
    check_observer_gain,
    check_sampled_observer,
    consensus_eigenvalues,
    graph_from_slots,
    innovation,
    min_observer_gain,
    observer_error_matrix,
    sampled_observer,
    sampled_observer_eigenvalues,
    sampled_observer_gain_range,
)
from .regulator import solve_regulator_equations

__all__ = [
    "REGULATOR_FORMS",
    "SampledObserver",
    "VehicleLaw",
    "check_observer_gain",
    "check_sampled_observer",
    "cohesion_input",
    "coupling_force_gain",
    "consensus_eigenvalues",
    "control_input",
    "design_vehicle_law",
    "graph_from_slots",
    "innovation",
    "min_observer_gain",
    "observer_error_matrix",
    "regulation_error",
    "sampled_observer",
    "sampled_observer_eigenvalues",
    "sampled_observer_gain_range",
]

#: ``continuous``: the regulator equations of the continuous vehicle (as the stacked
#: ``tracking = "regulator"`` law); ``sampled``: of the ZOH-sampled vehicle (zero error at
#: the samples on every path).
REGULATOR_FORMS = ("continuous", "sampled")


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
            f"{fmt_complex(fk)} of the leader's F (exp(f h) = {fmt_complex(np.exp(fk * h))}) "
            "the vehicle "
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
    F = as_square("leader F", F)
    l_ = F.shape[0]
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
    law, xhat, what, eta
        As :func:`regulation_error`.
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


def coupling_force_gain(B: Any, coupling: Any,
                        state_names: tuple[str, ...] | None = None) -> np.ndarray:
    """Kc = B^+ Gamma (:func:`plant_model.fleet.consensus_force_gain`, which refuses a coupling
    outside the actuators' reach, naming the state rows)."""
    from plant_model.fleet import consensus_force_gain
    return consensus_force_gain(B, coupling, state_names)
