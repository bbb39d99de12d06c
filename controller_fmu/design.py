"""The paper's LQ feedforward-feedback design (eq. 12-15, corrected: docs/theory.md section 2).

    (13)  A'P + P A - P S P + C'QC = 0,     S = B1 R^-1 B1',  A - S P Hurwitz
    (14)  (A - S P)' P1 + P1 F + P Bz = C'Q H   (Bz = 0 in the paper; see LinearSystem)
    (15)  (A - S P)' P2 + P2 K + P B2 = 0
    u = -(Kx xhat + Kz zhat + Kw what),  Kx = R^-1 B1'P, Kz = R^-1 B1'P1, Kw = R^-1 B1'P2

(14) and (15) are Sylvester equations with a unique solution if and only if no
eigenvalue of A - S P plus an eigenvalue of F (resp. K) is zero; the design checks this
and names the offending pair. Units: gains map state units to input units.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import LinAlgError, solve_continuous_are, solve_sylvester

from plant_model.linalg_checks import (
    ModelError,
    fmt_complex,
    uncontrollable_modes,
    unobservable_modes,
)
from plant_model.system import LinearSystem

__all__ = ["TrackingDesign", "lq_riccati_gain", "lq_tracking_design", "uncontrollable_modes",
           "unobservable_modes", "sylvester_resonances"]


@dataclass(frozen=True)
class TrackingDesign:
    """Result of :func:`lq_tracking_design` (python-control style names)."""

    P: np.ndarray
    P1: np.ndarray
    P2: np.ndarray
    Kx: np.ndarray
    Kz: np.ndarray
    Kw: np.ndarray
    closed_loop_poles: np.ndarray     #: eigenvalues of A - B1 Kx, sorted (real, then imaginary)
    residuals: dict[str, float]       #: relative residuals of (13), (14), (15)

    def gain_on_state(self) -> np.ndarray:
        """K_s with u = -K_s [x; w; z] (the plant's state order).

        Returns
        -------
        np.ndarray
            K_s = [Kx, Kw, Kz], m x (n + r + l).
        """
        return np.hstack([self.Kx, self.Kw, self.Kz])


def sylvester_resonances(Acl: np.ndarray, G: np.ndarray) -> list[tuple[complex, complex]]:
    """Pairs (lambda of Acl, mu of G) with lambda + mu = 0 (to a relative tolerance).

    The Sylvester equation Acl' X + X G = Y has a unique solution if and only if there is
    no such pair; tolerance |lambda + mu| <= 1e-8 (1 + max |lambda|, |mu|).

    Parameters
    ----------
    Acl : np.ndarray
        Closed-loop matrix A - S P, n x n, 1/s.
    G : np.ndarray
        Exosystem matrix (F or K), k x k, 1/s.

    Returns
    -------
    list[tuple[complex, complex]]
        The resonant pairs (empty if the solution is unique).
    """
    la = np.linalg.eigvals(Acl)
    mu = np.linalg.eigvals(G)
    scale = 1.0 + max(np.max(np.abs(la), initial=0.0), np.max(np.abs(mu), initial=0.0))
    return [(complex(a), complex(b)) for a in la for b in mu if abs(a + b) <= 1e-8 * scale]


def _rel(res: np.ndarray, *terms: np.ndarray) -> float:
    scale = sum(float(np.linalg.norm(t)) for t in terms) or 1.0
    return float(np.linalg.norm(res)) / scale


def _refuse_modes(bad: list, what: str, why: str) -> None:
    """ModelError "<what>: the mode(s) <eigenvalues> of A are not stable and <why>"."""
    if bad:
        raise ModelError(f"{what}: the mode(s) {', '.join(fmt_complex(z) for z in bad)} of A are "
                         f"not stable and {why}")


def _sorted_poles(poles: np.ndarray) -> np.ndarray:
    """Poles by real part, then imaginary part, real parts equal to 1e-9 of the largest
    |pole| counted equal: an order that rounding (another BLAS kernel) does not change, so a
    fleet's repeated poles print the same on every machine."""
    tol = 1e-9 * max(1.0, float(np.abs(poles).max(initial=0.0)))
    return poles[np.lexsort((poles.imag, np.round(poles.real / tol)))]


def lq_riccati_gain(A: np.ndarray, B1: np.ndarray, C: np.ndarray, Q: np.ndarray,
                    R: np.ndarray, *, where: str = "") -> tuple[np.ndarray, np.ndarray,
                                                              np.ndarray, float]:
    """The stabilizing solution P of (13) and the state-feedback gain Kx = R^-1 B1' P.

        A'P + P A - P S P + C'Q C = 0,    S = B1 R^-1 B1',    A - S P Hurwitz

    Checks first, naming the modes: (A, B1) stabilizable (PBH) and (C'QC, A) detectable;
    then that A - S P is Hurwitz. Shared by the stacked design (:func:`lq_tracking_design`)
    and the per-vehicle design of :mod:`controller_fmu.distributed`.

    Parameters
    ----------
    A : np.ndarray
        State matrix, n x n, 1/s.
    B1 : np.ndarray
        Input matrix, n x m.
    C : np.ndarray
        Tracked output matrix, p x n.
    Q : np.ndarray
        Output error weight, p x p (positive definite).
    R : np.ndarray
        Input weight, m x m (positive definite).
    where : str, optional
        Prefix of the error messages (e.g. "vehicle 3: ").

    Returns
    -------
    P : np.ndarray
        Stabilizing Riccati solution, n x n (symmetric).
    Kx : np.ndarray
        Gain R^-1 B1' P, m x n (input units per state unit).
    poles : np.ndarray
        Eigenvalues of A - B1 Kx, 1/s.
    residual : float
        Relative residual of (13).

    Raises
    ------
    ModelError
        If (A, B1) is not stabilizable, (C'QC, A) not detectable, or (13) has no
        stabilizing solution.
    """
    _refuse_modes(uncontrollable_modes(A, B1), f"{where}(A, B1) is not stabilizable",
                  "cannot be moved by u")
    _refuse_modes(unobservable_modes(A, C), f"{where}(C'QC, A) is not detectable",
                  "do not show in the tracked output C x")
    Rinv = np.linalg.inv(R)
    CQC = C.T @ Q @ C
    try:
        P = solve_continuous_are(A, B1, CQC, R)
    except (LinAlgError, ValueError) as exc:
        raise ModelError(f"{where}the Riccati equation (13) has no stabilizing solution: "
                         f"{exc}") from None
    P = 0.5 * (P + P.T)
    S = B1 @ Rinv @ B1.T
    poles = _sorted_poles(np.linalg.eigvals(A - S @ P))
    margin = 1e-9 * max(1.0, float(np.max(np.abs(poles))))
    if np.max(poles.real) >= -margin:
        raise ModelError(
            f"{where}the Riccati solution of (13) is not stabilizing: A - S P has the "
            "eigenvalue " + fmt_complex(poles[np.argmax(poles.real)])
        )
    residual = _rel(A.T @ P + P @ A - P @ S @ P + CQC, A.T @ P, P @ S @ P, CQC)
    return P, Rinv @ B1.T @ P, poles, residual


def lq_tracking_design(system: LinearSystem) -> TrackingDesign:
    """Solve (13)-(15) for ``system``; raise :class:`ModelError` naming what failed.

    P from the Riccati equation (13), P1 and P2 from the Sylvester equations (14) and
    (15); Kx = R^-1 B1'P, Kz = R^-1 B1'P1, Kw = R^-1 B1'P2 (module docstring).

    Parameters
    ----------
    system : LinearSystem
        The validated model (A, B1, B2, Bz, C, F, H, K, Q, R).

    Returns
    -------
    TrackingDesign
        P, P1, P2, the gains, the closed-loop poles (1/s) and the relative residuals.

    Raises
    ------
    ModelError
        If (A, B1) is not stabilizable, (C'QC, A) not detectable, (13) has no stabilizing
        solution, (14) or (15) has no unique solution, or a residual exceeds 1e-6.
    """
    A, B1, B2, Bz, C, F, H, K = (system.A, system.B1, system.B2, system.Bz, system.C,
                                 system.F, system.H, system.K)
    Q, R = system.Q, system.R
    P, Kx, poles, riccati_res = lq_riccati_gain(A, B1, C, Q, R)
    Rinv = np.linalg.inv(R)
    S = B1 @ Rinv @ B1.T
    Acl = A - S @ P
    for name, G in (("F", F), ("K", K)):
        pairs = sylvester_resonances(Acl, G)
        if pairs:
            lam, mu = pairs[0]
            eq = "(14)" if name == "F" else "(15)"
            raise ModelError(
                f"the Sylvester equation {eq} has no unique solution: eigenvalue "
                f"{fmt_complex(lam)} of A - S P plus eigenvalue {fmt_complex(mu)} of {name} is zero"
            )
    CQH = C.T @ Q @ H
    P1 = solve_sylvester(Acl.T, F, CQH - P @ Bz)
    P2 = solve_sylvester(Acl.T, K, -P @ B2)
    residuals = {
        "riccati_13": riccati_res,
        "sylvester_14": _rel(Acl.T @ P1 + P1 @ F + P @ Bz - CQH, Acl.T @ P1, P1 @ F, P @ Bz, CQH),
        "sylvester_15": _rel(Acl.T @ P2 + P2 @ K + P @ B2, Acl.T @ P2, P2 @ K, P @ B2),
    }
    for name, value in residuals.items():
        if not np.isfinite(value) or value > 1e-6:
            raise ModelError(f"the design is ill-conditioned: relative residual of {name} "
                             f"is {value:.3g}")
    G = Rinv @ B1.T
    return TrackingDesign(P=P, P1=P1, P2=P2, Kx=Kx, Kz=G @ P1, Kw=G @ P2,
                          closed_loop_poles=poles, residuals=residuals)
