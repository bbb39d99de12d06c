"""plant_model/noise_factor.py: the symmetric square root that colours the noise, and what it
buys: a seed's traces do not depend on the BLAS kernel, the thread count or the Dask worker
that ran them (issue 35)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st

from orchestrator.recording.reader import read_rrd_scalars
from plant_model.noise_factor import NOISE_STREAM, decoupled_blocks, psd_sqrt
from support.campaign import TIMING, rows
from support.dask_cluster import dask_cluster
from support.kernels import auv_cosim, kernel_env, loaded_kernel, usable_kernels, worst_difference


def _random_psd(rng: np.random.Generator, n: int, rank: int) -> np.ndarray:
    G = rng.standard_normal((n, rank))
    return G @ G.T


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 7), rank=st.integers(0, 7))
def test_the_root_is_symmetric_and_squares_to_the_matrix(seed, n, rank):
    M = _random_psd(np.random.default_rng(seed), n, min(rank, n))
    S = psd_sqrt(M)
    assert np.array_equal(S, S.T)
    np.testing.assert_allclose(S @ S, M, atol=1e-10 * (1 + np.abs(M).max()))
    assert np.linalg.eigvalsh(S).min() > -1e-10 * (1 + np.abs(S).max())


def test_the_root_agrees_with_scipys_sqrtm():
    M = _random_psd(np.random.default_rng(3), 6, 6) + np.eye(6)
    np.testing.assert_allclose(psd_sqrt(M), scipy.linalg.sqrtm(M).real, rtol=0, atol=1e-12)


def test_the_root_does_not_depend_on_the_eigenbasis_of_a_repeated_eigenvalue():
    """Two identical vehicles: eigenvalues repeated, so eigh may return any basis of each
    eigenspace; permuting the vehicles changes the basis it returns, not the root."""
    one = _random_psd(np.random.default_rng(5), 3, 3)
    M = scipy.linalg.block_diag(one, one) + 0.3 * np.kron(np.ones((2, 2)), one)  # coupled
    P = np.eye(6)[[3, 4, 5, 0, 1, 2]]
    w, V = np.linalg.eigh(M)
    Vp = np.linalg.eigh(P @ M @ P.T)[1]
    eigen_factor = V * np.sqrt(w)                          # the old, basis-dependent factor
    eigen_factor_p = P.T @ (Vp * np.sqrt(w))
    assert np.abs(eigen_factor - eigen_factor_p).max() > 1e-3   # the old factor moves
    np.testing.assert_allclose(P.T @ psd_sqrt(P @ M @ P.T) @ P, psd_sqrt(M), rtol=0,
                               atol=1e-14 * np.abs(M).max())


def test_a_diagonal_covariance_gets_the_exact_square_roots():
    d = np.array([2.0, 0.0, 3e-7, 1e4])
    assert np.array_equal(psd_sqrt(np.diag(d)), np.diag(np.sqrt(d)))


def test_a_direction_without_noise_gets_none():
    """A rank-one covariance: eigh returns its zero eigenvalues as +-1e-17, whose square
    roots (3e-9) would differ from kernel to kernel; they are taken as zero."""
    v = np.array([1.0, 2.0, -0.5])
    S = psd_sqrt(np.outer(v, v))
    null = np.array([2.0, -1.0, 0.0])
    assert np.abs(S @ null).max() < 1e-14
    np.testing.assert_allclose(S @ S, np.outer(v, v), atol=1e-14)


def test_the_blocks_are_the_connected_components():
    M = np.zeros((5, 5))
    M[0, 3] = M[3, 0] = 1.0
    M[np.diag_indices(5)] = 1.0
    M[2, 4] = M[4, 2] = 0.5
    assert [b.tolist() for b in decoupled_blocks(M)] == [[0, 3], [1], [2, 4]]
    assert decoupled_blocks(np.zeros((0, 0))) == []
    assert psd_sqrt(np.zeros((0, 0))).shape == (0, 0)


# ------------------------------------------------------------------ the same seed, everywhere
#: the three runs of the issue: the paper, a stacked fleet, a per-vehicle fleet over links
RUNS = {
    "paper": ["run", "--T", "3"],
    "formation-4": ["run", "--scenario", "formation-4", "--T", "3"],
    "per-vehicle-links": ["run", "--scenario", "formation-4", "--deployment", "per-vehicle",
                          "--architecture", "distributed", "--latency", "1", "--period", "2",
                          "--loss", "0.2", "--T", "6"],
}


def _record(out: Path, env: dict[str, str]) -> dict[str, dict]:
    got = {}
    for name, args in RUNS.items():
        auv_cosim([*args, "--quiet", "--out", str(out / name)], env)
        (rrd,) = (out / name).glob("*.rrd")
        summary = json.loads((out / name / "summary.json").read_text())
        assert summary["noise_stream"] == NOISE_STREAM
        got[name] = read_rrd_scalars(rrd)
    return got


@pytest.mark.slow
def test_a_seed_gives_the_same_traces_on_every_blas_kernel_and_thread_count(tmp_path):
    """Each run under every OpenBLAS kernel this CPU runs (at least three) and with 1 and 2
    BLAS threads: every trace within 1e-12 of its scale. The scale of an estimate is the
    largest of its estimator's estimates: a current estimate of 0.1 m/s is a difference of
    positions of 20-80 m, carried at their rounding (docs/theory.md, section 4)."""
    kernels = usable_kernels()
    if len(kernels) < 3:
        pytest.skip(f"this CPU runs only the OpenBLAS kernels {[a for _, a in kernels]}: "
                    "three are needed")
    configs = [(None, 1), (None, 2)] + [(name, 1) for name, _ in kernels[1:3]]
    reference = None
    for kernel, threads in configs:
        env = kernel_env(kernel, threads)
        arch, n = loaded_kernel(env)
        assert n == threads and (kernel is None or arch != kernels[0][1]), (kernel, arch)
        got = _record(tmp_path / f"{kernel}-{threads}", env)
        if reference is None:
            reference = got
            continue
        for name in RUNS:
            worst, where = worst_difference(reference[name], got[name])
            assert worst <= 1e-12, f"{name} under {arch} x{threads}: {where} differs by " \
                                   f"{worst:.3g} of its scale"


FLEET_SPEC = """
base = "formation-4"
seeds = "0-3"
seeds_per_task = 1
[sweep]
"simulation.T" = [2.0]
"""


@pytest.mark.slow
def test_a_campaign_gives_the_same_rows_whichever_kernel_its_worker_runs(tmp_path):
    """Two Dask workers on different OpenBLAS kernels run a fleet campaign: each row equals
    the row of a local run on the CPU's own kernel (floats to 1e-12, every other field
    exactly, run keys with the noise stream; a vector's entries to 1e-12 of its largest)."""
    kernels = usable_kernels()
    if len(kernels) < 2:
        pytest.skip("this CPU runs one OpenBLAS kernel only")
    spec = tmp_path / "fleet.toml"
    spec.write_text(FLEET_SPEC)
    auv_cosim(["campaign", str(spec), "--workers", "1", "--out", str(tmp_path / "local")],
              kernel_env(None))
    local = {r["run_key"]: r for r in rows(tmp_path / "local")}
    other = kernels[1][0]
    with dask_cluster(2, worker_env=[{}, {"OPENBLAS_CORETYPE": other}]) as cluster:
        from dask.distributed import Client
        with Client(cluster.address) as client:
            arch = client.run(lambda: __import__("threadpoolctl").threadpool_info()[0]
                              .get("architecture") if __import__("numpy") else None)
            pids = client.run(lambda: __import__("os").getpid())
        assert len(set(arch.values())) == 2, arch
        auv_cosim(["campaign", str(spec), "--scheduler", cluster.address, "--out",
                   str(tmp_path / "mixed")], kernel_env(None))
    mixed = rows(tmp_path / "mixed")
    kernel_of_pid = {pids[w]: arch[w] for w in pids}
    assert {kernel_of_pid[r["pid"]] for r in mixed} == set(arch.values()), \
        "both workers should have run rows"
    assert set(local) == {r["run_key"] for r in mixed}
    for r in mixed:
        want = local[r["run_key"]]
        versions = r["versions"] if isinstance(r["versions"], dict) else json.loads(r["versions"])
        assert versions["noise_stream"] == str(NOISE_STREAM)
        for k, v in r.items():
            if k in TIMING:
                continue
            if isinstance(v, float):
                assert v == pytest.approx(want[k], rel=1e-12, abs=1e-300), k
            elif isinstance(v, list) and v and isinstance(v[0], float):
                np.testing.assert_allclose(v, want[k], rtol=0, err_msg=k,   # of the vector's scale
                                           atol=1e-12 * np.abs(want[k]).max())
            else:
                assert v == want[k], k
