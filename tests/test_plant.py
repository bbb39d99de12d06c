"""plant_model.plant: seeded noise stream and the sampled plant."""
from __future__ import annotations

import numpy as np
import pytest

from plant_model.discretization import discretize
from plant_model.plant import NoiseStream, Plant, plant_output_layout

H = 0.01


@pytest.fixture(scope="module")
def model(paper_system):
    return discretize(paper_system, H)


def _inputs(steps, m, seed=123):
    return np.random.default_rng(seed).standard_normal((steps, m))


def _trace(model, s0, seed, U):
    plant = Plant(model, s0, seed)
    out = [plant.output.copy()]
    for u in U:
        plant.step(u)
        out.append(plant.output.copy())
    return np.array(out), plant


def test_output_layout(model):
    lay = plant_output_layout(model)
    assert [(k, v.start, v.stop) for k, v in lay.items()] == [
        ("y", 0, 2), ("ybar", 2, 4), ("x", 4, 6), ("w", 6, 8), ("z", 8, 10), ("e", 10, 12)]


def test_same_seed_same_trace_other_seed_other_trace(model, paper_system):
    U = _inputs(300, 2)
    s0 = paper_system.initial_state()
    a, _ = _trace(model, s0, 7, U)
    b, _ = _trace(model, s0, 7, U)
    c, _ = _trace(model, s0, 8, U)
    np.testing.assert_array_equal(a, b)
    assert np.all(np.isfinite(a))
    # every noisy channel differs for another seed
    assert np.all(np.abs(a[1:] - c[1:]).max(axis=0) > 1e-6)


def test_reset_replays_the_same_noise(model, paper_system):
    U = _inputs(100, 2)
    s0 = paper_system.initial_state()
    first, plant = _trace(model, s0, 3, U)
    plant.reset(s0)
    assert plant.k == 0
    again = [plant.output.copy()]
    for u in U:
        plant.step(u)
        again.append(plant.output.copy())
    np.testing.assert_array_equal(first, np.array(again))


def test_reset_does_not_alias_the_initial_state(model, paper_system):
    s0 = paper_system.initial_state()
    keep = s0.copy()
    plant = Plant(model, s0, 0)
    plant.step(np.ones(2))
    np.testing.assert_array_equal(s0, keep)


def test_step_follows_the_sampled_model_with_the_stream_rows(model, paper_system):
    """Reference loop built from all_rows: s[k+1] = Ad s + Bd u + v[k], y[k] = C x + n[k]."""
    steps, seed = 2500, 11                      # crosses the 2048-row block boundary
    U = _inputs(steps, 2)
    rows = NoiseStream.all_rows(model, seed, steps + 1)
    s = paper_system.initial_state()
    ns, p, n, r = model.ns, model.p, model.n, model.r
    C, Hm = paper_system.C, paper_system.H
    ref = []
    for k in range(steps + 1):
        x, z = s[:n], s[n + r:]
        ref.append(np.concatenate([C @ x + rows[k, ns:ns + p], Hm @ z + rows[k, ns + p:],
                                   s, Hm @ z - C @ x]))
        if k < steps:
            s = model.Ad @ s + model.Bd @ U[k] + rows[k, :ns]
    got, plant = _trace(model, paper_system.initial_state(), seed, U)
    assert plant.k == steps
    np.testing.assert_allclose(got, np.array(ref), rtol=1e-10, atol=1e-10)


def test_noiseless_plant_is_deterministic_and_exact(paper_system):
    model = discretize(paper_system.without_noise(), H)
    s0 = paper_system.initial_state()
    U = _inputs(50, 2)
    a, plant_a = _trace(model, s0, 1, U)
    b, _ = _trace(model, s0, 2, U)
    np.testing.assert_array_equal(a, b)         # the seed does not matter without noise
    s = s0.copy()
    for u in U:
        s = model.Ad @ s + model.Bd @ u
    np.testing.assert_allclose(plant_a.s, s, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("block", [1, 7, 2048, 5000])
def test_block_draws_equal_all_rows(model, block):
    steps, seed = 4500, 2024
    ref = NoiseStream.all_rows(model, seed, steps)
    stream = NoiseStream(model, seed, block=block)
    got = np.array([stream.next_row() for _ in range(steps)])
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)


def test_all_rows_depend_on_the_seed_only(model):
    a = NoiseStream.all_rows(model, 5, 100)
    np.testing.assert_array_equal(a, NoiseStream.all_rows(model, 5, 100))
    np.testing.assert_array_equal(a[:40], NoiseStream.all_rows(model, 5, 40))
    assert not np.allclose(a, NoiseStream.all_rows(model, 6, 100))


def test_empirical_noise_covariance_matches_qd_and_rd(model):
    """blkdiag(Qd, Rd) within sampling error (5 standard errors per entry)."""
    N = 200_000
    rows = NoiseStream.all_rows(model, 99, N)
    W = np.zeros((model.noise_dim, model.noise_dim))
    W[:model.ns, :model.ns] = model.Qd
    W[model.ns:, model.ns:] = model.Rd
    S = rows.T @ rows / N                        # the mean is known to be zero
    d = np.diag(W)
    se = np.sqrt((np.outer(d, d) + W ** 2) / N)  # std of a Gaussian sample covariance
    z = np.abs(S - W) / se
    assert z.max() < 5.0, f"worst entry {np.unravel_index(z.argmax(), z.shape)}: {z.max():.2f} SE"
    assert np.abs(rows.mean(axis=0)).max() < 5 * np.sqrt(d.max() / N)


def test_singular_noise_covariance_is_fine(paper_mapping):
    """Noise switched off in some directions: those rows are exactly zero."""
    from plant_model.system import LinearSystem
    paper_mapping.update(W_w=0.0, W_z=[[2.0, 0.0], [0.0, 0.0]], V_ybar=0.0,
                         noise_convention="per_sample")
    model = discretize(LinearSystem.from_mapping(paper_mapping), H)
    rows = NoiseStream.all_rows(model, 0, 1000)
    n, r, p, ns = model.n, model.r, model.p, model.ns
    assert not np.any(rows[:, n:n + r])          # w
    assert not np.any(rows[:, n + r + 1])        # second reference state
    assert not np.any(rows[:, ns + p:])          # ybar noise
    assert np.all(rows[:, :n].std(axis=0) > 1.0)
