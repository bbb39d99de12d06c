"""Sigma = Phi Sigma Phi' + G for a block lower-triangular Phi, block by block.

The error part of a distributed fleet's loop couples vehicle i only to itself and to the
vehicles it hears. When the communication graph has no cycle (every built-in fleet:
information flows from the leader backwards), ordering the vehicles so that each comes
after those it hears makes Phi block lower-triangular, and the Stein (discrete Lyapunov)
equation splits into one small equation per block pair i >= j::

    Sigma_ij - Phi_ii Sigma_ij Phi_jj' = G_ij + sum_{k in nz(i), l in nz(j), (k,l) != (i,j)}
                                          Phi_ik Sigma_kl Phi_jl'

whose right side holds only blocks already solved (k <= i, l <= j). Each is a discrete
Sylvester equation (I - Phi_jj kron Phi_ii) vec Sigma_ij = vec C, factorized once per pair
of distinct diagonal blocks (identical vehicles share them). For N = 100 vehicles of 34
states this is seconds where the dense solver of scipy takes minutes; both solve the same
equation (tested against scipy.linalg.solve_discrete_lyapunov).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.linalg import lu_factor, lu_solve, solve_discrete_lyapunov

__all__ = ["stein", "triangular_order"]


def triangular_order(Phi: np.ndarray, blocks: Sequence[np.ndarray]) -> list[int] | None:
    """An order of the blocks in which Phi is block lower-triangular, or None (a cycle).

    Parameters
    ----------
    Phi : np.ndarray
        n x n.
    blocks : Sequence[np.ndarray]
        Index arrays partitioning 0..n-1.

    Returns
    -------
    list[int] or None
        Block numbers, each after every block it depends on (Kahn's algorithm).
    """
    nb = len(blocks)
    deps = [set() for _ in range(nb)]
    for i, bi in enumerate(blocks):
        rows = Phi[bi]
        for j, bj in enumerate(blocks):
            if i != j and np.any(rows[:, bj]):
                deps[i].add(j)
    order, done = [], set()
    ready = [i for i in range(nb) if not deps[i]]
    waiting = {i: set(d) for i, d in enumerate(deps) if d}
    while ready:
        i = ready.pop(0)
        order.append(i)
        done.add(i)
        for k in [k for k, d in waiting.items() if i in d]:
            waiting[k].discard(i)
            if not waiting[k]:
                del waiting[k]
                ready.append(k)
    return order if len(order) == nb else None


def stein(Phi: np.ndarray, G: np.ndarray,
          blocks: Sequence[np.ndarray] | None = None) -> np.ndarray:
    """Sigma with Sigma = Phi Sigma Phi' + G (Phi stable, G symmetric).

    Block by block (module docstring) when ``blocks`` makes Phi block lower-triangular in
    some order; else the dense solver.

    Parameters
    ----------
    Phi : np.ndarray
        Stable n x n.
    G : np.ndarray
        Symmetric n x n.
    blocks : Sequence[np.ndarray] or None, optional
        Index arrays partitioning 0..n-1 (one per vehicle).

    Returns
    -------
    np.ndarray
        Sigma, symmetric n x n.
    """
    order = None if blocks is None else triangular_order(Phi, blocks)
    if order is None:
        S = solve_discrete_lyapunov(Phi, G)
        return 0.5 * (S + S.T)
    bl = [np.asarray(blocks[i]) for i in order]
    nb = len(bl)
    P = {(i, k): Phi[np.ix_(bl[i], bl[k])] for i in range(nb) for k in range(nb)
         if np.any(Phi[np.ix_(bl[i], bl[k])])}
    nz = [[k for k in range(nb) if (i, k) in P] for i in range(nb)]
    keys = [P[(i, i)].tobytes() if (i, i) in P else b"" for i in range(nb)]
    lus: dict[tuple[bytes, bytes], tuple] = {}
    S: dict[tuple[int, int], np.ndarray] = {}

    def get(k: int, l_: int) -> np.ndarray:
        return S[(k, l_)] if k >= l_ else S[(l_, k)].T

    for i in range(nb):
        Aii = P.get((i, i), np.zeros((bl[i].size, bl[i].size)))
        for j in range(i + 1):
            Bjj = P.get((j, j), np.zeros((bl[j].size, bl[j].size)))
            C = G[np.ix_(bl[i], bl[j])].copy()
            for k in nz[i]:
                acc = None
                for l_ in nz[j]:
                    if k == i and l_ == j:
                        continue
                    term = get(k, l_) @ P[(j, l_)].T
                    acc = term if acc is None else acc + term
                if acc is not None:
                    C += P[(i, k)] @ acc
            key = (keys[i], keys[j])
            if key not in lus:
                m, n = Aii.shape[0], Bjj.shape[0]
                lus[key] = lu_factor(np.eye(m * n) - np.kron(Bjj, Aii))
            X = lu_solve(lus[key], C.reshape(-1, order="F"))
            S[(i, j)] = X.reshape(C.shape, order="F")
    n = Phi.shape[0]
    out = np.zeros((n, n))
    for (i, j), X in S.items():
        out[np.ix_(bl[i], bl[j])] = X
        if i != j:
            out[np.ix_(bl[j], bl[i])] = X.T
    return 0.5 * (out + out.T)
