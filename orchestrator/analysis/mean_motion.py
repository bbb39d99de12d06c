"""Window sums of e e' and u u' along the deterministic mean motion of a sampled loop.

The mean motion X_{k+1} = Phi X_k from X_0, with e_k = E X_k and u_k = G X_k; wanted are

    ee = sum_{k0 <= k < K} e_k e_k',   uu = sum_{k0 <= k < K} u_k u_k'

over windows of up to millions of samples (3 h at h = 0.01 s). The loop as a whole does not
settle: its deterministic states v (a leader's planned path, the constant c = 1 carrying
the offsets, their exact estimates) are an exosystem on the unit circle (a Jordan block at
1 for a constant velocity, rotations for a periodic path). They are autonomous: in the order
[x; v] (x the rest, the *error part*)

    Phi = [A  B]      x_{k+1} = A x_k + B v_k,   v_{k+1} = S v_k,
          [0  S]

with A stable. The steady pattern x = Pi v solves the Sylvester equation

    Pi S = A Pi + B

(unique: no eigenvalue of A is one of S), and the deviation d_k = x_k - Pi v_k obeys
d_{k+1} = A d_k exactly, so

    e_k = C_e v_k + E_x d_k,  C_e = E_x Pi + E_v   (likewise u with G).

d decays geometrically: it is advanced one mat-vec per sample (Phi is sparse for a fleet)
until it is below the rounding of the state itself, ||d_k|| <= 2^-60 max(||X_0||, ||d_0||)
(max norms), or the window ends; from then on e_k = C_e v_k, and the rest of the window is

    C_e (sum_k v_k v_k') C_e'

with the m x m sum over blocks of ``block`` consecutive v's, each block the previous one
times S^block. The transient lasts about 40 time constants of the slowest error mode, so the
cost no longer grows with the window.

Accuracy, against the step loop X_{k+1} = Phi X_k in extended precision (entries relative
to sqrt(ee_ii ee_jj)), formation-4 and formation-100 over 1 h and 3 h: uu to 1e-11,
as the step loop in double precision; ee, the small steady error of the mean motion beside
positions that grow along the path, to 4e-11 (formation-4) and 1.2e-9 (formation-100), where
the double-precision step loop is off by 1.2e-9 and 6e-8 (its rounding of X cancels in
e = H v - C x; here the rounding of Pi, times the leader's position, is what is left). On
the centralized loops' windows (all transient) likewise: ee 4e-10 to 2e-8 off where the
step loop is 2e-9 to 1.2e-7 off (components above 1e-10 of the largest; those below are
the rounding of a cancellation in both).

Everything is fixed by the arguments (the block size is the caller's constant, no
threshold depends on the machine), so a run repeats its figures bit for bit.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

__all__ = ["steady_map", "window_mean_sums"]

#: d is dropped once ||d_k|| <= this x max(||X_0||, ||d_0||): below the last bit of the state
NEGLIGIBLE = 2.0 ** -60
#: entries of d below this x max(||X_0||, ||d_0||) are set to 0 after each block: decaying
#: further they would become subnormal numbers, whose arithmetic is about 100 times slower
FLUSH = 2.0 ** -200


def steady_map(A: Any, B: np.ndarray, S: np.ndarray) -> np.ndarray | None:
    """Pi with Pi S = A Pi + B, from (S' kron I - I kron A) vec Pi = vec B (sparse LU).

    Parameters
    ----------
    A : np.ndarray or sparse matrix
        The error part's transition, n x n.
    B : np.ndarray
        Its input from the exosystem, n x m.
    S : np.ndarray
        The exosystem's transition, m x m.

    Returns
    -------
    np.ndarray or None
        Pi, n x m; None when the equation is singular (an eigenvalue of A is one of S).
    """
    n, m = B.shape
    if m == 0:
        return np.zeros((n, 0))
    L = (sp.kron(sp.csr_matrix(S.T), sp.identity(n), format="csc")
         - sp.kron(sp.identity(m), sp.csr_matrix(A), format="csc"))
    try:
        Pi = splu(L.tocsc()).solve(B.flatten(order="F")).reshape((n, m), order="F")
    except RuntimeError:                    # exactly singular
        return None
    return Pi if np.all(np.isfinite(Pi)) else None


def _split(Phi: Any, D: np.ndarray) -> tuple[Any, np.ndarray, np.ndarray] | None:
    """(A, B, S) of Phi in the order [x; v] (module docstring), or None when v is not
    autonomous (Phi[v, x] != 0)."""
    R = np.flatnonzero(~D)
    V = np.flatnonzero(D)
    if sp.issparse(Phi):
        P = sp.csr_matrix(Phi)
        rows_R, rows_V = P[R], P[V]
        if rows_V[:, R].count_nonzero():
            return None
        return rows_R[:, R].tocsr(), rows_R[:, V].toarray(), rows_V[:, V].toarray()
    Phi = np.asarray(Phi, dtype=float)
    if np.any(Phi[np.ix_(V, R)]):
        return None
    return Phi[np.ix_(R, R)], Phi[np.ix_(R, V)], Phi[np.ix_(V, V)]


def window_mean_sums(Phi: Any, X: np.ndarray, k0: int, K: int, E: np.ndarray,
                     G: np.ndarray, block: int, deterministic: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The sums over samples k0 <= k < K of e e' and u u', e = E X_k and u = G X_k, along
    the mean X_{k+1} = Phi X_k from X_0 = ``X`` (module docstring: the deviation from the
    exosystem's steady pattern advanced until it is below rounding, the rest in closed form).

    Parameters
    ----------
    Phi : np.ndarray or sparse matrix
        The closed loop's transition matrix.
    X : np.ndarray
        The mean state at k = 0.
    k0, K : int
        The window.
    E, G : np.ndarray
        The maps from the state to the tracking error and to the control input.
    block : int
        Samples handled at once (the caller's constant: the figures depend on it in the
        last bits).
    deterministic : np.ndarray or None, optional
        Mask of the autonomous exosystem states v; None: none (then the whole state decays
        or is advanced to K).

    Returns
    -------
    tuple[np.ndarray, np.ndarray]
        The sums of e e' and of u u' (not yet divided by K - k0).
    """
    X = np.asarray(X, dtype=float)
    ee = np.zeros((E.shape[0], E.shape[0]))
    uu = np.zeros((G.shape[0], G.shape[0]))
    if K <= k0:
        return ee, uu
    D = np.zeros(X.size, dtype=bool) if deterministic is None else np.asarray(deterministic)
    parts = _split(Phi, D) if D.any() else None
    Pi = None if parts is None else steady_map(*parts)
    if Pi is None:                          # no autonomous exosystem: all of X is "x"
        D = np.zeros(X.size, dtype=bool)
        parts = _split(Phi, D)
        Pi = np.zeros((X.size, 0))
    assert parts is not None
    A, _, S = parts
    R = ~D
    Ex, Gx = sp.csr_matrix(E[:, R]), sp.csr_matrix(G[:, R])
    Ce = np.asarray(Ex @ Pi) + E[:, D]
    Cu = np.asarray(Gx @ Pi) + G[:, D]
    v = X[D]
    d = X[R] - Pi @ v
    scale = max(float(np.max(np.abs(X), initial=0.0)), float(np.max(np.abs(d), initial=0.0)))
    tiny = NEGLIGIBLE * scale
    transient = bool(np.max(np.abs(d), initial=0.0) > tiny)

    b = max(1, min(block, K))
    Vb = np.empty((v.size, b))                 # v_k .. v_{k+b-1}, the first block step by step
    for j in range(b):
        Vb[:, j] = v
        v = S @ v
    Sb = np.linalg.matrix_power(S, b)
    rows = np.empty((b, d.size)) if transient else np.empty((0, d.size))
    M = np.zeros((v.size, v.size))          # sum of v v' after the transient
    k = 0
    while k < K:
        nb, lo = min(b, K - k), max(k0 - k, 0)      # this block: samples k .. k + nb - 1
        if transient:
            for j in range(nb):
                rows[j] = d
                d = A @ d
            if lo < nb:
                cols = np.ascontiguousarray(rows[lo:nb].T)     # d_k as columns
                e = Ex @ cols + Ce @ Vb[:, lo:nb]
                u = Gx @ cols + Cu @ Vb[:, lo:nb]
                ee += e @ e.T
                uu += u @ u.T
            d[np.abs(d) < FLUSH * scale] = 0.0
            transient = bool(np.max(np.abs(d), initial=0.0) > tiny)
        elif lo < nb:
            M += Vb[:, lo:nb] @ Vb[:, lo:nb].T
        k += nb
        if k < K:
            Vb = Sb @ Vb
    ee += Ce @ M @ Ce.T
    uu += Cu @ M @ Cu.T
    return (ee + ee.T) / 2, (uu + uu.T) / 2
