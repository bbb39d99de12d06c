"""The factor that turns standard normal draws into correlated noise, one for every machine.

A noise row is ``v = S xi`` with ``xi`` standard normal and ``S S' = M`` for the noise's
covariance ``M``. Infinitely many factors satisfy ``S S' = M`` (any ``S U`` with ``U``
orthogonal), and a seed fixes ``xi``, so the factor decides the traces a seed gives. The
factor used here is the one that is unique for the matrix:

    S = M^(1/2) = V diag(sqrt(w)) V'        (M = V diag(w) V', the symmetric square root)

It does not depend on which eigenvectors an eigensolver returns for a repeated eigenvalue
(``V_i V_i'`` is the eigenspace's projector whatever basis ``V_i`` holds) nor on their
signs, so the same seed gives the same noise, to rounding, on every LAPACK/BLAS kernel and
thread count. The factor used before (noise stream 1) was ``V diag(sqrt(w))``: for the
repeated eigenvalues of a fleet of identical vehicles its columns were whatever basis the
kernel picked, and a seed's traces changed with the CPU.

Two refinements keep the result reproducible to rounding, not just mathematically unique:

- ``M`` is split into its decoupled blocks (connected components of its non-zero pattern)
  and each block gets its own square root (the square root of a block-diagonal matrix is
  block diagonal). A diagonal covariance gets ``sqrt`` of its diagonal, exactly, with no
  eigensolver at all; a fleet's covariance is one small block per vehicle.
- An eigenvalue at or below ``RANK_TOL * k * w_max`` of its k x k block is taken as zero
  (the numerical-rank rule of ``numpy.linalg.matrix_rank``, with a margin): a direction the
  noise does not excite comes out of an eigensolver as +-1e-17 w_max, whose square root
  (3e-9 of the block's scale) would otherwise differ from kernel to kernel.

``NOISE_STREAM`` numbers the noise a seed gives; it is recorded in every ``summary.json``
and in a campaign's run keys, so figures of two streams are never mixed.
"""
from __future__ import annotations

import numpy as np

__all__ = ["NOISE_STREAM", "RANK_TOL", "decoupled_blocks", "psd_sqrt"]

#: the noise a seed gives: 1 = eigenvector factor V sqrt(w) (machine dependent, before
#: 2026-11-29), 2 = the symmetric square root of each decoupled block (this module)
NOISE_STREAM = 2

#: eigenvalues at or below RANK_TOL * k * (largest eigenvalue) of a k x k block are zero
RANK_TOL = 64 * np.finfo(float).eps


def decoupled_blocks(M: np.ndarray) -> list[np.ndarray]:
    """The index sets of ``M``'s decoupled blocks: connected components of the graph with
    an edge i - j wherever ``M[i, j] != 0``, each sorted, ordered by their first index.

    Parameters
    ----------
    M : np.ndarray
        Square matrix, k x k.

    Returns
    -------
    list[np.ndarray]
        int64 index arrays that partition 0..k-1.
    """
    from scipy.sparse.csgraph import connected_components  # not on the import path of NOISE_STREAM
    k = M.shape[0]
    if k == 0:
        return []
    count, label = connected_components(M != 0, directed=False)
    blocks = [np.flatnonzero(label == c) for c in range(count)]
    return sorted(blocks, key=lambda b: int(b[0]))


def psd_sqrt(M: np.ndarray) -> np.ndarray:
    """The symmetric square root S of a symmetric positive semidefinite ``M``: S = S',
    S S = M, S positive semidefinite (module docstring).

    Per decoupled block B = V diag(w) V' (``numpy.linalg.eigh``):
    S_B = V diag(sqrt(w~)) V' with w~_i = w_i if w_i > RANK_TOL k max(w), else 0; a 1 x 1
    block gets sqrt(max(b, 0)). A singular M (noise switched off in some direction) is fine,
    unlike the Cholesky factorisation. Units: those of M's square root (M in m^2 -> S in m).

    Parameters
    ----------
    M : np.ndarray
        Symmetric positive semidefinite, k x k (symmetrised as (M + M') / 2).

    Returns
    -------
    np.ndarray
        S, k x k, exactly symmetric.
    """
    M = 0.5 * (np.asarray(M, dtype=float) + np.asarray(M, dtype=float).T)
    S = np.zeros_like(M)
    for idx in decoupled_blocks(M):
        if idx.size == 1:
            i = int(idx[0])
            S[i, i] = np.sqrt(max(M[i, i], 0.0))
            continue
        w, V = np.linalg.eigh(M[np.ix_(idx, idx)])
        top = float(w[-1])
        if top <= 0.0:
            continue
        root = np.where(w > RANK_TOL * idx.size * top, np.sqrt(np.clip(w, 0.0, None)), 0.0)
        block = (V * root) @ V.T
        S[np.ix_(idx, idx)] = 0.5 * (block + block.T)
    return S
