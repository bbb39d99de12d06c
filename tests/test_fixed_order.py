"""plant_model.fixed_order: products over a sparse map's non-zero entries in a fixed order,
checked against numpy's product and an explicit sum of IEEE doubles, and a row's value
whatever the other rows (a BLAS product's last bits depend on how many rows it gets)."""
from __future__ import annotations

import numpy as np
import pytest

from plant_model.fixed_order import quadratic_form, rows_times_transpose


def _sparse(rng, p, n, density):
    A = rng.standard_normal((p, n)) * (rng.random((p, n)) < density)
    A[0] = 0.0                                           # a row without an entry
    return A


def test_the_product_is_the_explicit_sum_in_column_order():
    rng = np.random.default_rng(3)
    X, A = rng.standard_normal((7, 9)), _sparse(rng, 5, 9, 0.4)
    got = rows_times_transpose(X, A)
    for k in range(7):
        for i in range(5):
            want = 0.0
            first = True
            for j in range(9):                           # Python floats: IEEE doubles
                if A[i, j] != 0.0:
                    term = float(X[k, j]) * float(A[i, j])
                    want, first = (term if first else want + term), False
            assert got[k, i] == want, (k, i)
    np.testing.assert_allclose(got, X @ A.T, rtol=1e-13, atol=1e-15)
    assert not got[:, 0].any()


def test_a_row_does_not_depend_on_the_other_rows():
    rng = np.random.default_rng(4)
    X, A = rng.standard_normal((1000, 60)), _sparse(rng, 40, 60, 0.2)
    whole = rows_times_transpose(X, A)
    for a, b in ((0, 1), (3, 517), (517, 1000)):
        assert np.array_equal(rows_times_transpose(X[a:b], A), whole[a:b])


def test_the_quadratic_form_agrees_with_numpy():
    rng = np.random.default_rng(5)
    X = rng.standard_normal((50, 12))
    M = np.kron(np.eye(4), (lambda B: B @ B.T)(rng.standard_normal((3, 3))))
    np.testing.assert_allclose(quadratic_form(X, M), np.einsum("ki,ij,kj->k", X, M, X),
                               rtol=1e-12)
    with pytest.raises(ValueError, match=r"X \(50, 12\) and A \(3, 4\) do not chain"):
        rows_times_transpose(X, np.ones((3, 4)))
