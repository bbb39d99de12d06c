"""Output regulation: zero steady-state error for persistent references (docs/theory.md section 7).

With a marginally stable exosystem (a constant offset, a straight run, a circle, a survey
pattern) the paper's law (eq. 12-15) exists but leaves a steady tracking error. The
regulator equations of Francis (1977) remove it. With the exogenous state v = [w; z]
(v' = S v, S = blkdiag(K, F)), the plant x' = A x + B1 u + Pv v, Pv = [B2, Bz], and the
error e = Hv v - C x, Hv = [0, H], find Pi (n x (r+l)) and Gamma (m x (r+l)) with

    Pi S = A Pi + B1 Gamma + Pv,        C Pi = Hv.

Then u = Gamma v - Kx (x - Pi v) with Kx from the same Riccati equation (13) gives
eps = x - Pi v, eps' = (A - B1 Kx) eps, so e = -C eps -> 0 for every exosystem motion.
The equations are solvable for every Pv, Hv if and only if, at every eigenvalue lambda of
S, the matrix [[A - lambda I, B1], [C, 0]] has full row rank n + p (lambda is not a
transmission zero of (A, B1, C) and there are at least as many inputs as outputs).

Both tracking modes are returned as one gain on the plant's state order [x; w; z]:

    lq:         u = -(Kx x + Kw w + Kz z)                        (the paper)
    regulator:  u = -Kx x + (Gamma + Kx Pi) [w; z]
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.linalg import lu_factor, lu_solve, schur

from plant_model.linalg_checks import ModelError, fmt_complex
from plant_model.memo import DesignCache
from plant_model.system import LinearSystem

from .design import TrackingDesign, lq_tracking_design

__all__ = ["TRACKING_MODES", "TrackingLaw", "solve_regulator_equations", "tracking_law"]

TRACKING_MODES = ("lq", "regulator")

#: tracking laws of this process, by the numbers they come from (plant_model.memo)
_LAW_CACHE = DesignCache("tracking_law")


def _pencil(A: np.ndarray, B1: np.ndarray, C: np.ndarray, lam: complex) -> np.ndarray:
    """[[A - lam I, B1], [C, 0]] (complex)."""
    n, m = B1.shape
    Mk = np.zeros((n + C.shape[0], n + m), dtype=complex)
    Mk[:n, :n] = A - lam * np.eye(n)
    Mk[:n, n:] = B1
    Mk[n:, :n] = C
    return Mk


def solve_regulator_equations(A: np.ndarray, B1: np.ndarray, C: np.ndarray, S: np.ndarray,
                              Pv: np.ndarray, Hv: np.ndarray, *,
                              exosystem: str = "S") -> tuple[np.ndarray, np.ndarray]:
    """(Pi, Gamma) with Pi S = A Pi + B1 Gamma + Pv and C Pi = Hv.

    Column by column in the complex Schur basis of S (S = U T U^H, T upper triangular):
    for the k-th Schur vector, ``[[A - T_kk I, B1], [C, 0]] [pi_k; gamma_k] =
    [sum_{j<k} pi_j T_jk - (Pv U)_k; (Hv U)_k]``; one LU factorisation per distinct
    eigenvalue.

    Parameters
    ----------
    A : np.ndarray
        Vehicle state matrix, n x n, 1/s.
    B1 : np.ndarray
        Control input matrix, n x m.
    C : np.ndarray
        Output matrix, p x n.
    S : np.ndarray
        Exosystem matrix, nv x nv, 1/s.
    Pv : np.ndarray
        How the exogenous state drives the vehicles, n x nv.
    Hv : np.ndarray
        The reference output of the exogenous state, p x nv.
    exosystem : str, optional
        Names S in error messages.

    Returns
    -------
    Pi : np.ndarray
        Steady-state map x = Pi v, n x nv.
    Gamma : np.ndarray
        Steady-state input u = Gamma v, m x nv.

    Raises
    ------
    ModelError
        Naming the eigenvalue at which the equations have no solution (or when m < p, or
        the solution is ill-conditioned).
    """
    n, m = B1.shape
    p = C.shape[0]
    nv = S.shape[0]
    if nv == 0:
        return np.zeros((n, 0)), np.zeros((m, 0))
    if m < p:
        raise ModelError(
            f"the regulator equations have no solution in general: {m} inputs cannot hold "
            f"{p} outputs on a persistent reference (need at least as many inputs as outputs)")
    T, U = schur(S.astype(complex), output="complex")
    PvU = Pv @ U
    HvU = Hv @ U
    Pi_t = np.zeros((n, nv), dtype=complex)
    Ga_t = np.zeros((m, nv), dtype=complex)
    factors: dict[tuple[float, float], object] = {}
    scale = 1.0 + float(np.abs(A).max(initial=0.0)) + float(np.abs(S).max(initial=0.0))
    for k in range(nv):
        lam = T[k, k]
        key = (round(lam.real, 12), round(lam.imag, 12))
        rhs = np.concatenate([Pi_t[:, :k] @ T[:k, k] - PvU[:, k], HvU[:, k]])
        if m == p:
            if key not in factors:
                Mk = _pencil(A, B1, C, lam)
                sv = np.linalg.svd(Mk, compute_uv=False)
                if sv[-1] <= 1e-10 * max(sv[0], scale):
                    raise ModelError(
                        "the regulator equations have no solution: at eigenvalue "
                        f"{fmt_complex(lam)} "
                        f"of the exosystem {exosystem}, [[A - lambda I, B1], [C, 0]] is "
                        f"singular (a transmission zero of (A, B1, C) at {fmt_complex(lam)})")
                factors[key] = lu_factor(Mk)
            sol = lu_solve(factors[key], rhs)
        else:
            Mk = _pencil(A, B1, C, lam)
            sol = np.linalg.lstsq(Mk, rhs, rcond=None)[0]
            res = np.linalg.norm(Mk @ sol - rhs)
            if res > 1e-8 * (1.0 + np.linalg.norm(rhs)):
                raise ModelError(
                    f"the regulator equations have no solution: at eigenvalue {fmt_complex(lam)} "
                    f"of the exosystem {exosystem}, [[A - lambda I, B1], [C, 0]] loses row "
                    f"rank (residual {res:.3g})")
        Pi_t[:, k] = sol[:n]
        Ga_t[:, k] = sol[n:]
    Uh = U.conj().T
    Pi = (Pi_t @ Uh).real
    Gamma = (Ga_t @ Uh).real
    res = max(np.linalg.norm(Pi @ S - A @ Pi - B1 @ Gamma - Pv),
              np.linalg.norm(C @ Pi - Hv))
    ref = 1.0 + np.linalg.norm(Pv) + np.linalg.norm(Hv)
    if not np.isfinite(res) or res > 1e-6 * ref * scale:
        raise ModelError(f"the regulator equations are ill-conditioned: residual {res:.3g}")
    return Pi, Gamma


@dataclass(frozen=True)
class TrackingLaw:
    """u = -Ks [x; w; z] for one tracking mode (see the module docstring)."""

    mode: str
    Ks: np.ndarray
    design: TrackingDesign
    Pi: np.ndarray | None = None       #: regulator: x -> Pi [w; z] in steady state
    Gamma: np.ndarray | None = None    #: regulator: u -> Gamma [w; z] + ... in steady state


def tracking_law(system: LinearSystem, mode: str = "lq",
                 design: TrackingDesign | None = None) -> TrackingLaw:
    """The gain of ``mode`` ('lq' or 'regulator') on the plant state [x; w; z].

    lq: Ks = [Kx, Kw, Kz]; regulator: Ks = [Kx, -(Gamma + Kx Pi)] (module docstring).
    For a fleet whose consensus protocol is a force (``system.meta["consensus"]``, a
    :class:`plant_model.fleet.ConsensusProtocol`) the law is designed on the in-plant system
    and the protocol force added: Ks = Ks_design - Kc.
    Without ``design``, solved once per process for identical numbers
    (:mod:`plant_model.memo`; the result's arrays are read-only).

    Parameters
    ----------
    system : LinearSystem
        The validated model.
    mode : str, optional
        One of :data:`TRACKING_MODES`.
    design : TrackingDesign or None, optional
        The LQ design of ``system`` if already solved (else solved here).

    Returns
    -------
    TrackingLaw
        u = -Ks [x; w; z], with the design and (regulator) Pi and Gamma.

    Raises
    ------
    ModelError
        If the mode is unknown, the design fails or the regulator equations have no
        solution.
    """
    if mode not in TRACKING_MODES:
        raise ModelError(f"unknown tracking mode {mode!r}; expected one of "
                         f"{', '.join(TRACKING_MODES)}")
    protocol = system.meta.get("consensus")
    if protocol is not None:      # a fleet whose consensus protocol is a force (plant_model.fleet)
        law = tracking_law(protocol.design, mode, design)
        total = law.Ks - protocol.gain                     # u = -Ks s + Kc s
        total.setflags(write=False)
        return replace(law, Ks=total)
    if design is not None:
        return _tracking_law(system, mode, design)
    key = (mode,) + tuple(getattr(system, k) for k in
                          ("A", "B1", "B2", "Bz", "C", "F", "H", "K", "Q", "R"))
    return _LAW_CACHE.get(key, lambda: _tracking_law(system, mode, lq_tracking_design(system)))


def _tracking_law(system: LinearSystem, mode: str, design: TrackingDesign) -> TrackingLaw:
    if mode == "lq":
        return TrackingLaw(mode, design.gain_on_state(), design)
    n, r, l_ = system.n, system.r, system.l
    p = system.p
    Pi_w, Ga_w = solve_regulator_equations(system.A, system.B1, system.C, system.K, system.B2,
                                           np.zeros((p, r)), exosystem="K (disturbance)")
    Pi_z, Ga_z = solve_regulator_equations(system.A, system.B1, system.C, system.F, system.Bz,
                                           system.H, exosystem="F (reference)")
    Pi = np.hstack([Pi_w, Pi_z])
    Gamma = np.hstack([Ga_w, Ga_z])
    Ks = np.hstack([design.Kx, -(Gamma + design.Kx @ Pi)])
    assert Ks.shape == (system.m, n + r + l_)
    return TrackingLaw(mode, Ks, design, Pi, Gamma)
