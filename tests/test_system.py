"""plant_model.system: LinearSystem.from_mapping validation and the stacked model."""
from __future__ import annotations

import numpy as np
import pytest

from plant_model.linalg_checks import ModelError
from plant_model.system import MATRIX_NAMES, NOISE_CONVENTIONS, LinearSystem


# valid input --------------------------------------------------------------------------
def test_paper_system_sizes_and_values(paper_system, paper_mapping):
    s = paper_system
    assert s.dims == {"n": 2, "m": 2, "r": 2, "p": 2, "l": 2}
    for name in MATRIX_NAMES:
        np.testing.assert_array_equal(getattr(s, name), np.array(paper_mapping[name]))
    np.testing.assert_array_equal(s.initial_state(), [0.0, 0.0, 0.3, 0.4, 0.4, 0.5])
    assert s.noise_convention == "intensity"


def test_rectangular_sizes_are_inferred():
    rng = np.random.default_rng(0)
    n, m, r, p, l_ = 3, 1, 4, 2, 5
    s = LinearSystem.from_mapping({
        "A": rng.standard_normal((n, n)), "B1": rng.standard_normal((n, m)),
        "B2": rng.standard_normal((n, r)), "C": rng.standard_normal((p, n)),
        "F": -np.eye(l_), "H": rng.standard_normal((p, l_)), "K": -np.eye(r),
    })
    assert (s.n, s.m, s.r, s.p, s.l) == (n, m, r, p, l_)
    # defaults: Q = R = I, no noise, zero initial state
    np.testing.assert_array_equal(s.Q, np.eye(p))
    np.testing.assert_array_equal(s.R, np.eye(m))
    for name, size in (("W_x", n), ("W_w", r), ("W_z", l_), ("V_y", p), ("V_ybar", p)):
        np.testing.assert_array_equal(getattr(s, name), np.zeros((size, size)))
    np.testing.assert_array_equal(s.initial_state(), np.zeros(n + r + l_))


def test_scalar_means_scalar_times_identity(paper_mapping):
    paper_mapping.update(Q=3.0, R=0.5, W_x=2, V_ybar=0.25)
    s = LinearSystem.from_mapping(paper_mapping)
    np.testing.assert_array_equal(s.Q, 3.0 * np.eye(2))
    np.testing.assert_array_equal(s.R, 0.5 * np.eye(2))
    np.testing.assert_array_equal(s.W_x, 2.0 * np.eye(2))
    np.testing.assert_array_equal(s.V_ybar, 0.25 * np.eye(2))


def test_to_mapping_round_trip(paper_system):
    d = paper_system.to_mapping()
    again = LinearSystem.from_mapping(d)
    for k in MATRIX_NAMES + ("x0", "w0", "z0"):
        np.testing.assert_array_equal(getattr(again, k), getattr(paper_system, k))
    assert again.noise_convention == paper_system.noise_convention
    assert isinstance(d["A"], list)         # JSON-ready


def test_with_changes_revalidates(paper_system):
    s = paper_system.with_changes(R=2.0)
    np.testing.assert_array_equal(s.R, 2 * np.eye(2))
    np.testing.assert_array_equal(s.A, paper_system.A)
    with pytest.raises(ModelError, match="R must be positive definite"):
        paper_system.with_changes(R=-1.0)


def test_without_noise_zeroes_every_intensity_only(paper_system):
    s = paper_system.without_noise()
    for k in ("W_x", "W_w", "W_z", "V_y", "V_ybar"):
        assert not np.any(getattr(s, k))
    for k in ("A", "B1", "B2", "C", "F", "H", "K", "Q", "R"):
        np.testing.assert_array_equal(getattr(s, k), getattr(paper_system, k))


def test_augmented_model_blocks(paper_system):
    s = paper_system
    Ac, Bc, Wc = s.augmented()
    n, r, l_ = s.n, s.r, s.l
    x, w, z = slice(0, n), slice(n, n + r), slice(n + r, n + r + l_)
    np.testing.assert_array_equal(Ac[x, x], s.A)
    np.testing.assert_array_equal(Ac[x, w], s.B2)
    np.testing.assert_array_equal(Ac[w, w], s.K)
    np.testing.assert_array_equal(Ac[z, z], s.F)
    for blk in ((x, z), (w, x), (w, z), (z, x), (z, w)):
        assert not np.any(Ac[blk])
    np.testing.assert_array_equal(Bc[x], s.B1)
    assert not np.any(Bc[n:])
    np.testing.assert_array_equal(Wc, np.diag([2.0] * 6))


def test_error_and_measurement_matrices(paper_system):
    s = paper_system
    rng = np.random.default_rng(1)
    x, w, z = rng.standard_normal(2), rng.standard_normal(2), rng.standard_normal(2)
    st = np.concatenate([x, w, z])
    np.testing.assert_allclose(s.error_matrix() @ st, s.H @ z - s.C @ x, rtol=1e-14)
    np.testing.assert_allclose(s.measurement_matrix() @ st,
                               np.concatenate([s.C @ x, s.H @ z]), rtol=1e-14)


# bad input ---------------------------------------------------------------------------
@pytest.mark.parametrize("drop", ["A", "B1", "B2", "C", "F", "H", "K"])
def test_missing_matrix_is_named(paper_mapping, drop):
    del paper_mapping[drop]
    with pytest.raises(ModelError, match=rf"^missing system matrices: {drop}$"):
        LinearSystem.from_mapping(paper_mapping)


def test_all_missing_matrices_are_listed():
    with pytest.raises(ModelError) as exc:
        LinearSystem.from_mapping({"A": [[-1.0]], "C": [[1.0]]})
    assert str(exc.value) == "missing system matrices: B1, B2, F, H, K"


def test_unknown_keys_are_named(paper_mapping):
    paper_mapping["G"] = [[1.0]]
    paper_mapping["Rr"] = 1.0
    with pytest.raises(ModelError, match=r"^unknown system entries: G, Rr$"):
        LinearSystem.from_mapping(paper_mapping)


@pytest.mark.parametrize("name, value, got, want", [
    ("A", np.ones((2, 3)), "2x3", "2x2"),
    ("B1", np.ones((3, 2)), "3x2", "2x?"),
    ("B2", np.ones((1, 2)), "1x2", "2x?"),
    ("C", np.ones((2, 3)), "2x3", "?x2"),
    ("F", np.ones((3, 2)), "3x2", "3x3"),
    ("H", np.ones((2, 3)), "2x3", "2x2"),
    ("H", np.ones((3, 2)), "3x2", "2x2"),
    ("K", np.ones((3, 3)), "3x3", "2x2"),
    ("Q", np.eye(3), "3x3", "2x2"),
    ("R", np.eye(1), "1x1", "2x2"),
    ("W_x", np.eye(3), "3x3", "2x2"),
    ("W_w", np.eye(1), "1x1", "2x2"),
    ("W_z", np.eye(4), "4x4", "2x2"),
    ("V_y", np.eye(3), "3x3", "2x2"),
    ("V_ybar", np.ones((2, 1)), "2x1", "2x2"),
])
def test_wrong_shape_names_matrix_and_shapes(paper_mapping, name, value, got, want):
    paper_mapping[name] = value
    with pytest.raises(ModelError) as exc:
        LinearSystem.from_mapping(paper_mapping)
    msg = str(exc.value)
    assert msg.startswith(f"{name}:"), msg
    assert f"wrong shape {got}" in msg and f"expected {want}" in msg, msg


@pytest.mark.parametrize("name, value, msg", [
    ("x0", [0.0, 0.0, 0.0], "x0: wrong length 3, expected 2"),
    ("w0", [1.0], "w0: wrong length 1, expected 2"),
    ("z0", [1.0, 2.0, 3.0], "z0: wrong length 3, expected 2"),
])
def test_wrong_initial_state_length_is_named(paper_mapping, name, value, msg):
    paper_mapping[name] = value
    with pytest.raises(ModelError, match=f"^{msg}$"):
        LinearSystem.from_mapping(paper_mapping)


@pytest.mark.parametrize("name", ["A", "B1", "B2", "C", "F", "H", "K", "Q", "R",
                                  "W_x", "W_w", "W_z", "V_y", "V_ybar"])
@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_non_finite_matrix_entry_is_named(paper_mapping, name, bad):
    M = np.array(paper_mapping[name], dtype=float)
    M[1, 0] = bad
    paper_mapping[name] = M
    with pytest.raises(ModelError) as exc:
        LinearSystem.from_mapping(paper_mapping)
    assert f"{name}[2,1] = {bad}" in str(exc.value) and "not finite" in str(exc.value)


@pytest.mark.parametrize("name", ["x0", "w0", "z0"])
def test_non_finite_initial_state_is_named(paper_mapping, name):
    paper_mapping[name] = [0.0, float("nan")]
    with pytest.raises(ModelError, match=rf"{name}\[2\] = nan is not finite"):
        LinearSystem.from_mapping(paper_mapping)


@pytest.mark.parametrize("name", ["Q", "R", "W_x", "W_w", "W_z", "V_y", "V_ybar"])
@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_non_finite_scalar_is_named(paper_mapping, name, bad):
    """A scalar where a matrix is expected (scalar * I) must be finite, too."""
    paper_mapping[name] = bad
    with pytest.raises(ModelError) as exc:
        LinearSystem.from_mapping(paper_mapping)
    msg = str(exc.value)
    assert msg.startswith(name) and "not finite" in msg, msg


@pytest.mark.parametrize("name", ["Q", "R", "W_x", "V_y"])
def test_non_numeric_scalar_is_named(paper_mapping, name):
    paper_mapping[name] = "two"
    with pytest.raises(ModelError, match=rf"^{name}: not a number: 'two'$"):
        LinearSystem.from_mapping(paper_mapping)


@pytest.mark.parametrize("name, value", [
    ("Q", 0.0), ("Q", -1.0), ("Q", [[1.0, 0.0], [0.0, 0.0]]), ("Q", [[1.0, 2.0], [2.0, 1.0]]),
    ("R", 0.0), ("R", -2.0), ("R", [[1.0, 0.0], [0.0, -1e-3]]),
])
def test_weights_must_be_positive_definite(paper_mapping, name, value):
    paper_mapping[name] = value
    with pytest.raises(ModelError, match=rf"^{name} must be positive definite; its smallest eigenvalue is"):
        LinearSystem.from_mapping(paper_mapping)


@pytest.mark.parametrize("name", ["Q", "R"])
def test_weights_must_be_symmetric(paper_mapping, name):
    paper_mapping[name] = [[2.0, 0.1], [0.0, 2.0]]
    with pytest.raises(ModelError, match=rf"^{name} is not symmetric: {name}\[\d,\d\]"):
        LinearSystem.from_mapping(paper_mapping)


@pytest.mark.parametrize("name", ["W_x", "W_w", "W_z", "V_y", "V_ybar"])
def test_noise_must_not_be_negative(paper_mapping, name):
    paper_mapping[name] = [[1.0, 0.0], [0.0, -0.5]]
    with pytest.raises(ModelError) as exc:
        LinearSystem.from_mapping(paper_mapping)
    msg = str(exc.value)
    assert msg.startswith(f"{name} must be positive semidefinite") and "-0.5" in msg, msg


@pytest.mark.parametrize("name", ["W_x", "W_w", "W_z", "V_y", "V_ybar"])
def test_negative_scalar_noise_is_refused(paper_mapping, name):
    paper_mapping[name] = -2.0
    with pytest.raises(ModelError, match=rf"^{name} must be positive semidefinite.*-2"):
        LinearSystem.from_mapping(paper_mapping)


@pytest.mark.parametrize("name", ["W_x", "W_w", "W_z", "V_y", "V_ybar"])
def test_noise_must_be_symmetric(paper_mapping, name):
    paper_mapping[name] = [[2.0, 0.3], [-0.3, 2.0]]
    with pytest.raises(ModelError) as exc:
        LinearSystem.from_mapping(paper_mapping)
    msg = str(exc.value)
    assert msg.startswith(f"{name} is not symmetric") and f"{name}[1,2] = 0.3" in msg, msg


def test_zero_noise_is_allowed(paper_mapping):
    paper_mapping.update(W_x=0.0, V_y=[[0.0, 0.0], [0.0, 0.0]])
    s = LinearSystem.from_mapping(paper_mapping)
    assert not np.any(s.W_x) and not np.any(s.V_y)


@pytest.mark.parametrize("conv", NOISE_CONVENTIONS)
def test_known_noise_conventions(paper_mapping, conv):
    paper_mapping["noise_convention"] = conv
    assert LinearSystem.from_mapping(paper_mapping).noise_convention == conv


def test_unknown_noise_convention_is_named(paper_mapping):
    paper_mapping["noise_convention"] = "psd"
    with pytest.raises(ModelError) as exc:
        LinearSystem.from_mapping(paper_mapping)
    msg = str(exc.value)
    assert "noise_convention 'psd'" in msg
    assert "intensity" in msg and "per_sample" in msg
