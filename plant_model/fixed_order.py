"""Products of a trace (rows = samples) with a sparse constant matrix, summed in a fixed
order without BLAS: the same bits on every machine, BLAS kernel and thread count, and for a
row whatever the other rows (a BLAS product's last bits depend on the kernel, and on how many
rows it is given: on the chunks a run is cut in).

The matrices of a fleet are sparse (the error map picks each vehicle's position, the cost
weights are block diagonal): summing over the non-zero entries only is also faster than a
dense product (formation-100's error map: 300 non-zero entries of 300 x 600).
"""
from __future__ import annotations

import numpy as np

__all__ = ["quadratic_form", "rows_times_transpose"]


def rows_times_transpose(X: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``X @ A.T`` summed over the non-zero entries of each row of ``A``, in increasing
    column order:

        out[k, i] = sum_{j: A[i, j] != 0} X[k, j] A[i, j]      (left to right)

    Parameters
    ----------
    X : np.ndarray
        (K, n) samples.
    A : np.ndarray
        (p, n) constant matrix.

    Returns
    -------
    np.ndarray
        (K, p); a row of ``A`` without a non-zero entry gives zeros.
    """
    X = np.asarray(X, dtype=np.float64)
    A = np.asarray(A, dtype=np.float64)
    if X.ndim != 2 or A.ndim != 2 or X.shape[1] != A.shape[1]:
        raise ValueError(f"rows_times_transpose: X {X.shape} and A {A.shape} do not chain "
                         "(X has one column per column of A)")
    out = np.zeros((X.shape[0], A.shape[0]))
    rows, cols = np.nonzero(A)                  # row-major: columns increasing in a row
    if rows.size == 0:
        return out
    starts = np.searchsorted(rows, np.arange(A.shape[0]))
    rank = np.arange(rows.size) - starts[rows]  # which term of its row each entry is
    for t in range(int(rank.max()) + 1):
        pick = rank == t
        r, c = rows[pick], cols[pick]
        term = X[:, c] * A[r, c]
        if t == 0:
            out[:, r] = term
        else:
            out[:, r] += term
    return out


def quadratic_form(X: np.ndarray, M: np.ndarray) -> np.ndarray:
    """Per row k the quadratic form ``x_k' M x_k`` in a fixed order (no BLAS):
    (``rows_times_transpose(X, M.T)`` * X) summed along the row (numpy's pairwise sum).

    Parameters
    ----------
    X : np.ndarray
        (K, n) samples.
    M : np.ndarray
        (n, n) weight.

    Returns
    -------
    np.ndarray
        (K,).
    """
    return np.sum(rows_times_transpose(X, np.asarray(M, dtype=np.float64).T) * X, axis=1)
