"""The block-by-block Stein solver against scipy's dense one."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_discrete_lyapunov

from orchestrator.analysis.block_stein import stein, triangular_order
from orchestrator.analysis.distributed_verdict import vehicle_blocks
from orchestrator.analysis.per_vehicle import distributed_loop_of
from orchestrator.scenario import load_scenario


def _random(nb: int, size: int, cyclic: bool, seed: int = 0):
    rng = np.random.default_rng(seed)
    n = nb * size
    perm = rng.permutation(n)                  # blocks need not be contiguous
    blocks = [perm[i * size:(i + 1) * size] for i in range(nb)]
    Phi = np.zeros((n, n))
    for i in range(nb):
        Phi[np.ix_(blocks[i], blocks[i])] = 0.5 * rng.standard_normal((size, size)) / np.sqrt(size)
        for j in range(i):
            if rng.random() < 0.5:
                Phi[np.ix_(blocks[i], blocks[j])] = 0.3 * rng.standard_normal((size, size))
    if cyclic:
        Phi[np.ix_(blocks[0], blocks[-1])] = 0.01
    order = rng.permutation(nb)                # a shuffled block order: the solver finds one
    blocks = [blocks[k] for k in order]
    M = rng.standard_normal((n, n))
    return Phi, M @ M.T, blocks


@pytest.mark.parametrize("cyclic", [False, True])
def test_equals_the_dense_solver(cyclic):
    Phi, G, blocks = _random(6, 4, cyclic)
    assert np.max(np.abs(np.linalg.eigvals(Phi))) < 1
    assert (triangular_order(Phi, blocks) is None) == cyclic
    S = stein(Phi, G, blocks)
    ref = solve_discrete_lyapunov(Phi, G)
    assert np.abs(S - ref).max() < 1e-10 * np.abs(ref).max()
    assert np.abs(S - Phi @ S @ Phi.T - G).max() < 1e-10 * np.abs(G).max()


def test_a_fleet_loop_solves_vehicle_by_vehicle():
    sc = load_scenario("formation-4")
    loop = distributed_loop_of(sc, "kalman", "regulator", sc.distributed)
    R = ~loop.deterministic
    Phi = loop.Phi[np.ix_(R, R)]
    G = loop.Gam[R] @ loop.W @ loop.Gam[R].T
    blocks = vehicle_blocks(loop)
    assert sorted(np.concatenate(blocks).tolist()) == list(range(R.sum()))
    assert triangular_order(Phi, blocks) is not None      # formation-4's graph has no cycle
    S = stein(Phi, G, blocks)
    ref = solve_discrete_lyapunov(Phi, G)
    assert np.abs(S - ref).max() < 1e-8 * np.abs(ref).max()
