"""plant_model.linalg_checks: shape / finiteness / definiteness checks and PBH tests."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plant_model.linalg_checks import (
    ModelError,
    as_matrix,
    as_vector,
    check_symmetric_pd,
    check_symmetric_psd,
    uncontrollable_modes,
    unobservable_modes,
)


def test_model_error_is_a_value_error():
    assert issubclass(ModelError, ValueError)


# as_matrix ------------------------------------------------------------------------
def test_as_matrix_returns_float_copy_with_shape():
    M = as_matrix("A", [[1, 2], [3, 4]], (2, 2))
    assert M.dtype == float
    np.testing.assert_array_equal(M, [[1.0, 2.0], [3.0, 4.0]])


def test_as_matrix_reads_a_flat_list_as_one_row():
    assert as_matrix("C", [1.0, 2.0, 3.0]).shape == (1, 3)


def test_as_matrix_none_in_shape_means_any_size():
    assert as_matrix("B1", np.ones((3, 5)), (3, None)).shape == (3, 5)


def test_as_matrix_wrong_shape_names_matrix_and_both_shapes():
    with pytest.raises(ModelError) as exc:
        as_matrix("B1", np.ones((3, 2)), (2, None))
    msg = str(exc.value)
    assert msg.startswith("B1:")
    assert "3x2" in msg and "2x?" in msg


@pytest.mark.parametrize("bad, where", [
    ([[1.0, float("nan")], [0.0, 1.0]], "[1,2]"),
    ([[1.0, 0.0], [float("inf"), 1.0]], "[2,1]"),
    ([[1.0, 0.0], [0.0, -float("inf")]], "[2,2]"),
])
def test_as_matrix_non_finite_entry_is_named(bad, where):
    with pytest.raises(ModelError) as exc:
        as_matrix("F", bad)
    msg = str(exc.value)
    assert f"F{where}" in msg and "not finite" in msg


def test_as_matrix_scalar_is_refused():
    with pytest.raises(ModelError, match=r"^H: expected a matrix, got the scalar 3\.0"):
        as_matrix("H", 3.0)


def test_as_matrix_3d_is_refused():
    with pytest.raises(ModelError, match=r"^A: expected a 2-D matrix.*3 dimensions"):
        as_matrix("A", np.zeros((2, 2, 2)))


@pytest.mark.parametrize("bad", ["abc", [[1.0, "x"]], [[1.0, 2.0], [3.0]]])
def test_as_matrix_non_numeric_is_refused(bad):
    with pytest.raises(ModelError, match=r"^K: not a numeric matrix"):
        as_matrix("K", bad)


# as_vector ------------------------------------------------------------------------
def test_as_vector_accepts_scalar_as_length_one():
    np.testing.assert_array_equal(as_vector("x0", 2.5, 1), [2.5])


def test_as_vector_wrong_length_names_vector():
    with pytest.raises(ModelError, match=r"^z0: wrong length 3, expected 2$"):
        as_vector("z0", [1, 2, 3], 2)


def test_as_vector_non_finite_entry_is_named():
    with pytest.raises(ModelError, match=r"w0\[2\] = nan is not finite"):
        as_vector("w0", [0.0, float("nan")], 2)


def test_as_vector_matrix_is_refused():
    with pytest.raises(ModelError, match=r"^x0: expected a vector"):
        as_vector("x0", [[1.0, 2.0], [3.0, 4.0]])


# definiteness ---------------------------------------------------------------------
def test_symmetric_psd_accepts_singular_psd():
    check_symmetric_psd("W", np.array([[1.0, 1.0], [1.0, 1.0]]))
    check_symmetric_psd("W", np.zeros((3, 3)))
    check_symmetric_psd("W", np.zeros((0, 0)))


def test_asymmetric_is_refused_naming_both_entries():
    M = np.array([[1.0, 0.5], [0.2, 1.0]])
    with pytest.raises(ModelError) as exc:
        check_symmetric_psd("V_y", M)
    msg = str(exc.value)
    assert "V_y is not symmetric" in msg
    assert ("V_y[1,2] = 0.5" in msg and "V_y[2,1] = 0.2" in msg) or \
           ("V_y[2,1] = 0.2" in msg and "V_y[1,2] = 0.5" in msg)


def test_negative_eigenvalue_is_refused_with_the_eigenvalue():
    with pytest.raises(ModelError) as exc:
        check_symmetric_psd("W_x", np.diag([1.0, -0.5]))
    msg = str(exc.value)
    assert "W_x must be positive semidefinite" in msg and "-0.5" in msg


def test_definite_refuses_singular_and_names_smallest_eigenvalue():
    with pytest.raises(ModelError) as exc:
        check_symmetric_pd("Q", np.diag([2.0, 0.0]))
    msg = str(exc.value)
    assert "Q must be positive definite" in msg and "smallest eigenvalue is 0" in msg


def test_definite_accepts_spd():
    check_symmetric_pd("R", np.array([[2.0, 1.0], [1.0, 2.0]]))


# PBH tests ------------------------------------------------------------------------
def test_uncontrollable_unstable_mode_is_found():
    A = np.diag([1.0, -2.0])
    B = np.array([[0.0], [1.0]])
    modes = uncontrollable_modes(A, B)
    assert len(modes) == 1 and abs(modes[0] - 1.0) < 1e-12


def test_uncontrollable_stable_mode_is_ignored_unless_asked():
    A = np.diag([1.0, -2.0])
    B = np.array([[1.0], [0.0]])
    assert uncontrollable_modes(A, B) == []
    modes = uncontrollable_modes(A, B, only_unstable=False)
    assert len(modes) == 1 and abs(modes[0] + 2.0) < 1e-12


def test_marginal_mode_counts_as_unstable():
    A = np.array([[0.0, 1.0], [-1.0, 0.0]])        # eigenvalues +-1j
    B = np.zeros((2, 1))
    modes = sorted(uncontrollable_modes(A, B), key=lambda z: z.imag)
    np.testing.assert_allclose(modes, [-1j, 1j], atol=1e-12)


def test_discrete_time_uses_the_unit_circle():
    Ad = np.diag([0.5, 1.2])
    C = np.array([[1.0, 0.0]])
    modes = unobservable_modes(Ad, C, continuous=False)
    assert len(modes) == 1 and abs(modes[0] - 1.2) < 1e-12
    # a stable continuous-time reading of the same eigenvalue 0.5 / 1.2 would flag both
    assert len(unobservable_modes(np.diag([0.5, 1.2]), np.zeros((1, 2)))) == 2


def test_unobservable_is_the_dual_of_uncontrollable():
    A = np.array([[1.0, 1.0], [0.0, 2.0]])
    C = np.array([[1.0, 0.0]])                      # observable: C e1 != 0 and A couples
    assert unobservable_modes(A, C) == []
    C2 = np.array([[0.0, 1.0]])                     # x1 (mode 1) not seen
    modes = unobservable_modes(A, C2)
    assert len(modes) == 1 and abs(modes[0] - 1.0) < 1e-12


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), m=st.integers(1, 4))
def test_generic_pairs_are_controllable(seed, n, m):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) + 2.0 * np.eye(n)
    B = rng.standard_normal((n, m))
    # a random pair is controllable; compare with the rank of the controllability matrix
    ctrb = np.hstack([np.linalg.matrix_power(A, k) @ B for k in range(n)])
    s = np.linalg.svd(ctrb, compute_uv=False)
    if s[-1] > 1e-6 * s[0]:
        assert uncontrollable_modes(A, B, only_unstable=False) == []


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 6), m=st.integers(1, 4),
       lam=st.floats(0.0, 3.0))
def test_hidden_uncontrollable_mode_is_found_in_any_basis(seed, n, m, lam):
    """A = T [[lam, 0], [a, A2]] T^-1, B = T [0; B2]: lam is uncontrollable whatever T is."""
    rng = np.random.default_rng(seed)
    A2 = rng.standard_normal((n - 1, n - 1))
    Ab = np.zeros((n, n))
    Ab[0, 0] = lam
    Ab[1:, 0] = rng.standard_normal(n - 1)          # the hidden mode drives the rest
    Ab[1:, 1:] = A2
    Bb = np.zeros((n, m))
    Bb[1:] = rng.standard_normal((n - 1, m))
    T = rng.standard_normal((n, n)) + 3.0 * np.eye(n)
    A = T @ Ab @ np.linalg.inv(T)
    B = T @ Bb
    modes = uncontrollable_modes(A, B)
    assert any(abs(z - lam) < 1e-6 * (1 + np.linalg.norm(A)) for z in modes)
    # the dual statement on (A', B')
    modes = unobservable_modes(A.T, B.T)
    assert any(abs(z - lam) < 1e-6 * (1 + np.linalg.norm(A)) for z in modes)
