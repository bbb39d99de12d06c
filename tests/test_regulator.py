"""Output regulation (controller_fmu.regulator): the Francis equations and the tracking law.

    Pi S = A Pi + B1 Gamma + Pv,    C Pi = Hv
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.linalg import block_diag, expm, solve_sylvester

from controller_fmu.regulator import (
    TRACKING_MODES,
    solve_regulator_equations,
    tracking_law,
)
from plant_model.linalg_checks import ModelError, uncontrollable_modes
from plant_model.system import LinearSystem


def _residuals(A, B1, C, S, Pv, Hv, Pi, Ga):
    r1 = np.linalg.norm(Pi @ S - A @ Pi - B1 @ Ga - Pv)
    r2 = np.linalg.norm(C @ Pi - Hv)
    return r1, r2


def _kron_solve(A, B1, C, S, Pv, Hv):
    """The same equations as one linear system in vec(Pi), vec(Gamma) (column-major)."""
    n, m = B1.shape
    p, nv = C.shape[0], S.shape[0]
    In, Iv = np.eye(n), np.eye(nv)
    M = np.block([[np.kron(Iv, A) - np.kron(S.T, In), np.kron(Iv, B1)],
                  [np.kron(Iv, C), np.zeros((nv * p, nv * m))]])
    rhs = np.concatenate([-Pv.reshape(-1, order="F"), Hv.reshape(-1, order="F")])
    sol = np.linalg.solve(M, rhs)
    return sol[:n * nv].reshape((n, nv), order="F"), sol[n * nv:].reshape((m, nv), order="F")


def _rosenbrock_margin(A, B1, C, S):
    """Smallest relative singular value of [[A - lam I, B1], [C, 0]] over the eigenvalues of S."""
    n, m = B1.shape
    worst = np.inf
    for lam in np.linalg.eigvals(S):
        M = np.block([[A - lam * np.eye(n), B1], [C, np.zeros((C.shape[0], m))]])
        sv = np.linalg.svd(M, compute_uv=False)
        worst = min(worst, sv[-1] / sv[0])
    return worst


def _exosystem(kind: str, size: int, rng) -> np.ndarray:
    if kind == "random":
        return rng.normal(size=(size, size))
    # the persistent exosystems of the product: constant, ramp (Jordan), oscillator
    blocks = {"constant": np.zeros((1, 1)), "ramp": np.array([[0.0, 1.0], [0.0, 0.0]]),
              "oscillator": np.array([[0.0, 0.7], [-0.7, 0.0]])}
    B = blocks[kind]
    return block_diag(*([B] * max(1, size // B.shape[0])))


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.filter_too_much])
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 5), m=st.integers(1, 3),
       nv=st.integers(1, 4), kind=st.sampled_from(["random", "constant", "ramp", "oscillator"]))
def test_regulator_equations_on_random_systems(seed, n, m, nv, kind):
    assume(m <= n)
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    B1 = rng.normal(size=(n, m))
    C = rng.normal(size=(m, n))                 # m == p
    assume(not uncontrollable_modes(A, B1))     # stabilizable
    S = _exosystem(kind, nv, rng)
    nv = S.shape[0]
    Pv = rng.normal(size=(n, nv))
    Hv = rng.normal(size=(m, nv))
    assume(_rosenbrock_margin(A, B1, C, S) > 1e-4)   # no transmission zero near eig(S)
    Pi, Ga = solve_regulator_equations(A, B1, C, S, Pv, Hv)
    assert Pi.shape == (n, nv) and Ga.shape == (m, nv)
    assert Pi.dtype == float and Ga.dtype == float     # real, though solved in complex Schur form
    scale = 1.0 + np.linalg.norm(Pv) + np.linalg.norm(Hv)
    r1, r2 = _residuals(A, B1, C, S, Pv, Hv, Pi, Ga)
    size = 1.0 + np.linalg.norm(Pi) + np.linalg.norm(Ga)
    assert r1 < 1e-8 * scale * size and r2 < 1e-8 * scale * size, (r1, r2)
    # m == p: the solution is unique; it equals the Kronecker-form solution
    Pk, Gk = _kron_solve(A, B1, C, S, Pv, Hv)
    np.testing.assert_allclose(Pi, Pk, rtol=1e-6, atol=1e-8 * size)
    np.testing.assert_allclose(Ga, Gk, rtol=1e-6, atol=1e-8 * size)


def test_more_inputs_than_outputs_has_a_solution():
    rng = np.random.default_rng(3)
    n, m, p = 4, 3, 2
    A, B1, C = rng.normal(size=(n, n)), rng.normal(size=(n, m)), rng.normal(size=(p, n))
    S = np.array([[0.0, 1.0], [0.0, 0.0]])
    Pv, Hv = rng.normal(size=(n, 2)), rng.normal(size=(p, 2))
    Pi, Ga = solve_regulator_equations(A, B1, C, S, Pv, Hv)
    r1, r2 = _residuals(A, B1, C, S, Pv, Hv, Pi, Ga)
    assert r1 < 1e-9 and r2 < 1e-9


# plant with C (sI - A)^-1 B1 = -s / ((s + 1)(s + 2)): a differentiator-like zero at s = 0
A_ZERO0 = np.diag([-1.0, -2.0])
B_ZERO0 = np.array([[1.0], [1.0]])
C_ZERO0 = np.array([[1.0, -2.0]])


def test_transmission_zero_at_a_constant_reference_is_refused():
    # the plant really has the zero: its DC gain is 0
    assert abs((C_ZERO0 @ np.linalg.solve(-A_ZERO0, B_ZERO0)).item()) < 1e-15
    with pytest.raises(ModelError) as err:
        solve_regulator_equations(A_ZERO0, B_ZERO0, C_ZERO0, np.zeros((1, 1)),
                                  np.zeros((2, 1)), np.ones((1, 1)), exosystem="F (reference)")
    msg = str(err.value)
    assert "eigenvalue 0 " in msg and "transmission zero" in msg and "F (reference)" in msg, msg


def test_transmission_zero_at_an_oscillator_frequency_is_refused():
    # C (sI - A)^-1 B1 = (s^2 + 1) / ((s + 1)(s + 2)(s + 3)): zeros at +-1j
    A = np.diag([-1.0, -2.0, -3.0])
    B1 = np.ones((3, 1))
    C = np.array([[1.0, -5.0, 5.0]])
    G = (C @ np.linalg.solve(1j * np.eye(3) - A, B1)).item()
    assert abs(G) < 1e-14
    S = np.array([[0.0, 1.0], [-1.0, 0.0]])
    with pytest.raises(ModelError) as err:
        solve_regulator_equations(A, B1, C, S, np.zeros((3, 2)), np.array([[1.0, 0.0]]))
    msg = str(err.value)
    assert "transmission zero" in msg and ("0+1j" in msg or "0-1j" in msg), msg
    # at another frequency the same plant is fine
    Pi, Ga = solve_regulator_equations(A, B1, C, 2.0 * S, np.zeros((3, 2)), np.array([[1.0, 0.0]]))
    assert max(_residuals(A, B1, C, 2.0 * S, np.zeros((3, 2)), np.array([[1.0, 0.0]]), Pi, Ga)) < 1e-10


def test_fewer_inputs_than_outputs_is_refused_clearly():
    A, B1, C = -np.eye(3), np.array([[1.0], [0.0], [1.0]]), np.eye(3)[:2]
    with pytest.raises(ModelError) as err:
        solve_regulator_equations(A, B1, C, np.zeros((1, 1)), np.zeros((3, 1)), np.ones((2, 1)))
    msg = str(err.value)
    assert "1 input" in msg and "2 outputs" in msg and "at least as many inputs as outputs" in msg, msg


# --------------------------------------------------------------------------------------
# tracking_law: the closed loop, exactly (expm of the continuous closed loop)
def _system(z0, w0=(0.3,)):
    # x = [position, velocity] of a damped spring-mass, a constant disturbance force w,
    # reference z = [position, velocity] of a ramp (F a Jordan block)
    return LinearSystem.from_mapping({
        "A": [[0.0, 1.0], [-2.0, -1.0]], "B1": [[0.0], [1.0]], "B2": [[0.0], [1.0]],
        "C": [[1.0, 0.0]], "F": [[0.0, 1.0], [0.0, 0.0]], "H": [[1.0, 0.0]], "K": [[0.0]],
        "x0": [0.0, 0.0], "w0": list(w0), "z0": list(z0)})


def _error(sys, mode, t):
    Ac, Bc, _ = sys.augmented()
    law = tracking_law(sys, mode)
    return (sys.error_matrix() @ expm((Ac - Bc @ law.Ks) * t) @ sys.initial_state()).item()


@pytest.mark.parametrize("z0", [[2.0, 0.0], [2.0, 0.5]], ids=["constant", "ramp"])
def test_regulator_law_has_zero_steady_error_and_lq_does_not(z0):
    sys = _system(z0)
    e_reg = [_error(sys, "regulator", t) for t in (40.0, 60.0)]
    e_lq = [_error(sys, "lq", t) for t in (40.0, 60.0)]
    assert max(map(abs, e_reg)) < 1e-8, e_reg
    assert min(map(abs, e_lq)) > 1.0, e_lq
    assert abs(_error(sys, "regulator", 0.0)) == pytest.approx(2.0)   # it had to move
    # steady state of the regulator: x = Pi v, u = Gamma v with v = [w; z]
    law = tracking_law(sys, "regulator")
    Pi_z = law.Pi[:, 1:]
    np.testing.assert_allclose(sys.C @ Pi_z, sys.H, atol=1e-12)


def test_lq_steady_error_with_constant_reference_is_the_theoretical_one():
    """u = -(Kx x + Kw w + Kz z): x -> Pi_cl v, e -> (Hv - C Pi_cl) v (here exactly 1.48)."""
    sys = _system([2.0, 0.0])
    law = tracking_law(sys, "lq")
    n = sys.n
    Kx, Kv = law.Ks[:, :n], law.Ks[:, n:]
    S = block_diag(sys.K, sys.F)
    Pi = solve_sylvester(-(sys.A - sys.B1 @ Kx), S, np.hstack([sys.B2, sys.Bz]) - sys.B1 @ Kv)
    v = np.concatenate([sys.w0, sys.z0])
    e_ss = ((np.hstack([np.zeros((1, 1)), sys.H]) - sys.C @ Pi) @ v).item()
    assert _error(sys, "lq", 60.0) == pytest.approx(e_ss, abs=1e-9)
    assert abs(e_ss) > 1.0


def test_unknown_tracking_mode_lists_the_modes():
    sys = _system([1.0, 0.0])
    with pytest.raises(ModelError) as err:
        tracking_law(sys, "integral")
    msg = str(err.value)
    assert "'integral'" in msg and all(mode in msg for mode in TRACKING_MODES), msg


def test_regulator_law_refuses_a_plant_with_a_zero_at_the_reference():
    sys = LinearSystem.from_mapping({
        "A": A_ZERO0.tolist(), "B1": B_ZERO0.tolist(), "B2": [[1.0], [0.0]],
        "C": C_ZERO0.tolist(), "F": [[0.0]], "H": [[1.0]], "K": [[-1.0]], "z0": [1.0]})
    tracking_law(sys, "lq")                       # the paper's law exists
    with pytest.raises(ModelError, match=r"eigenvalue 0 of the exosystem F \(reference\).*"
                                         r"transmission zero"):
        tracking_law(sys, "regulator")
