"""plant_model.discretization: ZOH and Van Loan against direct numerical integrals."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad_vec
from scipy.linalg import block_diag, expm

from plant_model.discretization import discretize, van_loan, zoh
from plant_model.linalg_checks import ModelError


def _bd_integral(Ac, Bc, h):
    """int_0^h expm(Ac t) dt Bc by adaptive quadrature."""
    val, err = quad_vec(lambda t: expm(Ac * t) @ Bc, 0.0, h, epsabs=1e-13, epsrel=1e-12)
    return val


def _qd_integral(Ac, Wc, h):
    """int_0^h expm(Ac t) Wc expm(Ac' t) dt by adaptive quadrature."""
    def f(t):
        E = expm(Ac * t)
        return E @ Wc @ E.T
    val, err = quad_vec(f, 0.0, h, epsabs=1e-13, epsrel=1e-12)
    return val


@pytest.mark.parametrize("h", [0.01, 0.1, 0.7])
def test_paper_model_against_integrals(paper_system, h):
    Ac, Bc, Wc = paper_system.augmented()
    dm = discretize(paper_system, h)
    np.testing.assert_allclose(dm.Ad, expm(Ac * h), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(dm.Bd, _bd_integral(Ac, Bc, h), rtol=1e-9, atol=1e-12)
    Qref = _qd_integral(Ac, Wc, h)
    np.testing.assert_allclose(dm.Qd, Qref, rtol=1e-9, atol=1e-12 * np.abs(Qref).max())
    # for a small step, Qd is about Wc h (to O(|Ac| h) = 10 % here: K has the eigenvalue -9)
    if h == 0.01:
        np.testing.assert_allclose(dm.Qd, Wc * h, atol=0.1 * 2 * h)
    np.testing.assert_allclose(dm.Rd, block_diag(paper_system.V_y, paper_system.V_ybar) / h,
                               rtol=1e-15)


def test_bd_against_riemann_sum(paper_system):
    """A second, quadrature-free reference: midpoint rule on 20,000 sub-intervals."""
    h = 0.2
    Ac, Bc, _ = paper_system.augmented()
    N = 20000
    dt = h / N
    step = expm(Ac * dt)
    E = expm(Ac * dt / 2)
    acc = np.zeros_like(Bc)
    for _ in range(N):
        acc += E @ Bc
        E = step @ E
    np.testing.assert_allclose(zoh(Ac, Bc, h)[1], acc * dt, rtol=1e-7, atol=1e-10)


def test_scalar_closed_forms():
    a, b, w, h = -0.7, 1.3, 2.5, 0.3
    Ad, Bd = zoh(np.array([[a]]), np.array([[b]]), h)
    assert Ad[0, 0] == pytest.approx(np.exp(a * h), rel=1e-14)
    assert Bd[0, 0] == pytest.approx(b * (np.exp(a * h) - 1) / a, rel=1e-13)
    Qd = van_loan(np.array([[a]]), np.array([[w]]), h)
    assert Qd[0, 0] == pytest.approx(w * (np.exp(2 * a * h) - 1) / (2 * a), rel=1e-13)


def test_unstable_and_oscillatory_dynamics():
    """Van Loan is exact for any Ac, not only a stable one."""
    Ac = np.array([[0.3, 2.0, 0.0], [-2.0, 0.3, 1.0], [0.0, 0.0, 0.5]])
    Wc = np.array([[1.0, 0.2, 0.0], [0.2, 0.5, 0.1], [0.0, 0.1, 2.0]])
    h = 0.5
    np.testing.assert_allclose(van_loan(Ac, Wc, h), _qd_integral(Ac, Wc, h), rtol=1e-9)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), ns=st.integers(1, 6), m=st.integers(1, 4),
       h=st.floats(1e-3, 1.0))
def test_random_models_against_integrals(seed, ns, m, h):
    rng = np.random.default_rng(seed)
    Ac = rng.standard_normal((ns, ns))
    Bc = rng.standard_normal((ns, m))
    G = rng.standard_normal((ns, ns))
    Wc = G @ G.T
    Ad, Bd = zoh(Ac, Bc, h)
    np.testing.assert_allclose(Ad, expm(Ac * h), rtol=1e-11, atol=1e-13)
    np.testing.assert_allclose(Bd, _bd_integral(Ac, Bc, h), rtol=1e-8, atol=1e-11)
    Qd = van_loan(Ac, Wc, h)
    Qref = _qd_integral(Ac, Wc, h)
    np.testing.assert_allclose(Qd, Qref, rtol=1e-8, atol=1e-11 * np.abs(Qref).max())
    np.testing.assert_array_equal(Qd, Qd.T)                # exactly symmetric
    assert np.linalg.eigvalsh(Qd).min() >= -1e-12 * np.abs(Qd).max()


def test_per_sample_convention(paper_mapping):
    from plant_model.system import LinearSystem
    paper_mapping["noise_convention"] = "per_sample"
    paper_mapping["W_x"] = [[2.0, 0.5], [0.5, 1.0]]
    paper_mapping["V_ybar"] = [[3.0, 0.0], [0.0, 1.0]]
    s = LinearSystem.from_mapping(paper_mapping)
    for h in (0.01, 0.5):
        dm = discretize(s, h)
        np.testing.assert_array_equal(dm.Qd, s.augmented()[2])
        np.testing.assert_array_equal(dm.Rd, block_diag(s.V_y, s.V_ybar))
        # the deterministic part does not depend on the noise convention
        np.testing.assert_allclose(dm.Ad, expm(s.augmented()[0] * h), rtol=1e-12)


def test_intensity_measurement_noise_scales_with_one_over_h(paper_system):
    V = block_diag(paper_system.V_y, paper_system.V_ybar)
    for h in (0.001, 0.01, 0.25):
        np.testing.assert_allclose(discretize(paper_system, h).Rd, V / h, rtol=1e-15)


def test_model_layout(paper_system):
    dm = discretize(paper_system, 0.01)
    assert (dm.n, dm.r, dm.l, dm.p, dm.ns, dm.noise_dim) == (2, 2, 2, 2, 6, 10)
    assert dm.h == 0.01
    np.testing.assert_array_equal(dm.M, paper_system.measurement_matrix())
    np.testing.assert_array_equal(dm.E, paper_system.error_matrix())


@pytest.mark.parametrize("h", [0.0, -0.01, float("nan"), float("inf"), -float("inf")])
def test_bad_step_is_refused(paper_system, h):
    with pytest.raises(ModelError) as exc:
        discretize(paper_system, h)
    msg = str(exc.value)
    assert f"step h = {float(h)} s" in msg and "positive finite" in msg


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_overflow_is_reported(make_scalar):
    s = make_scalar(A=[[800.0]])
    with pytest.raises(ModelError, match=r"sampled model at h = 1\.0 s overflows"):
        discretize(s, 1.0)
