"""The stacked fleet system (plant_model.fleet) against hand computations of paper eq. 1-2,
and the formation-4 scenario's closed loop against output-regulation / LQ theory.

Conventions (plant_model.graph): vehicles 1..N, an edge (j, i, a_ij) means vehicle i hears
vehicle j; the pinning (i, a_i0) means vehicle i hears the leader. Per vehicle (eq. 1):

    x_i' = A_ii x_i + Gamma [ sum_j a_ij ((x_j - delta_j) - (x_i - delta_i))
                              + a_i0 (T_i z - (x_i - delta_i)) ] + ...
"""
from __future__ import annotations

import copy
import json
import tomllib

import numpy as np
import pytest
from scipy.linalg import block_diag, solve_sylvester

from controller_fmu.regulator import tracking_law
from orchestrator.analysis.reference import run_monolithic
from orchestrator.running import build, scenario_config
from orchestrator.scenario import SCENARIO_DIR, load_scenario
from orchestrator.scenario.fleet import fleet_spec_from_dict
from plant_model.fleet import fleet_system, resolve_fleet_spec
from plant_model.linalg_checks import ModelError
from support.loop import run_cosimulation

MATRICES = ("A", "B1", "B2", "Bz", "C", "F", "H", "K", "x0", "w0", "z0", "Q", "R",
            "W_x", "W_w", "W_z", "V_y", "V_ybar")

# --------------------------------------------------------------------------------------
# a hand-worked 3-vehicle fleet of generic vehicles (p = 2 states, q = r = 1, s = 2)
A_II = [np.array([[-1.0, 2.0], [0.0, -3.0]]),
        np.array([[0.0, 1.0], [-2.0, -1.0]]),
        np.array([[-0.5, 0.0], [1.0, -4.0]])]
C_I = [np.array([[1.0, 1.0], [0.0, 2.0]]),          # different invertible C per vehicle,
       np.array([[2.0, 0.0], [1.0, 1.0]]),          # so T_i = C_i^-1 H and delta_i = C_i^-1 d_i
       np.eye(2)]                                   # differ per vehicle
B1_I = [np.array([[0.0], [1.0]]), np.array([[1.0], [1.0]]), np.array([[0.0], [2.0]])]
B2_I = [np.array([[1.0], [0.0]]), np.array([[0.0], [1.0]]), np.array([[1.0], [1.0]])]
GAMMA = np.array([[0.5, 0.2], [-0.1, 1.5]])         # non-identity coupling
F_L = np.array([[0.0, 1.0], [-1.0, 0.0]])
H_L = np.array([[1.0, 0.0], [0.5, 1.0]])
Z0_L = np.array([1.0, 0.0])
D_I = [np.array([1.0, 0.0]), np.array([0.0, -2.0]), np.array([3.0, 1.0])]
# 0 -> 1 (a_10 = 2), 1 -> 2 (a_21 = 0.5), 1 -> 3 (a_31 = 1), 2 -> 3 (a_32 = 3)
EDGES = [[1, 2, 0.5], [1, 3, 1.0], [2, 3, 3.0]]
PINNING = [[1, 2.0]]


def generic_spec(C=None, offsets=True, edges=EDGES, pinning=PINNING, coupling=GAMMA) -> dict:
    C = C_I if C is None else C
    vehicles = []
    for i in range(3):
        v = {"model": "generic",
             "params": {"A": A_II[i].tolist(), "B1": B1_I[i].tolist(), "B2": B2_I[i].tolist(),
                        "C": C[i].tolist()},
             "current": {"time_constant": 10.0 * (i + 1), "sigma": 0.1, "w0": [0.01 * i]},
             "Q": float(i + 1), "R": 0.5, "W_x": 0.01, "V_y": 0.04}
        if offsets:
            v["offset"] = D_I[i].tolist()
        vehicles.append(v)
    return {"vehicles": vehicles,
            "graph": {"edges": copy.deepcopy(edges), "pinning": copy.deepcopy(pinning),
                      "coupling": None if coupling is None else np.asarray(coupling).tolist()},
            "leader": {"kind": "explicit", "F": F_L.tolist(), "H": H_L.tolist(),
                       "z0": Z0_L.tolist(), "W_z": 0.0}}


def test_stacked_system_of_three_vehicles_equals_the_hand_computation():
    sys = fleet_system(generic_spec())
    G = GAMMA
    Z = np.zeros((2, 2))
    # eq. 1-2: block (i, i) = A_ii - (sum_j a_ij + a_i0) Gamma, block (i, j) = a_ij Gamma
    A = np.block([
        [A_II[0] - 2.0 * G, Z, Z],                              # hears the leader only (a_10 = 2)
        [0.5 * G, A_II[1] - 0.5 * G, Z],                        # hears 1 (0.5)
        [1.0 * G, 3.0 * G, A_II[2] - (1.0 + 3.0) * G],          # hears 1 (1) and 2 (3)
    ])
    np.testing.assert_allclose(sys.A, A, rtol=0, atol=1e-14)

    T = [np.linalg.inv(C) @ H_L for C in C_I]                   # C_i T_i = H: leader state
    delta = [np.linalg.inv(C) @ d for C, d in zip(C_I, D_I)]     # C_i delta_i = d_i
    # Bz on z = [z_l; c]: pinning term a_i0 Gamma T_i, then the offset column
    # Gamma (sum_j a_ij (delta_i - delta_j) + a_i0 delta_i)
    Bz = np.zeros((6, 3))
    Bz[0:2, :2] = 2.0 * G @ T[0]
    Bz[0:2, 2] = G @ (2.0 * delta[0])
    Bz[2:4, 2] = G @ (0.5 * (delta[1] - delta[0]))
    Bz[4:6, 2] = G @ (1.0 * (delta[2] - delta[0]) + 3.0 * (delta[2] - delta[1]))
    np.testing.assert_allclose(sys.Bz, Bz, rtol=0, atol=1e-13)

    H = np.block([[H_L, D_I[0][:, None]], [H_L, D_I[1][:, None]], [H_L, D_I[2][:, None]]])
    np.testing.assert_array_equal(sys.H, H)
    np.testing.assert_array_equal(sys.F, block_diag(F_L, [[0.0]]))
    np.testing.assert_array_equal(sys.z0, [1.0, 0.0, 1.0])     # c(0) = 1
    np.testing.assert_array_equal(sys.B1, block_diag(*B1_I))
    np.testing.assert_array_equal(sys.B2, block_diag(*B2_I))
    np.testing.assert_array_equal(sys.C, block_diag(*C_I))
    np.testing.assert_allclose(sys.K, np.diag([-0.1, -0.05, -1.0 / 30.0]), rtol=1e-15)
    np.testing.assert_allclose(sys.W_w, np.diag([2 * 0.01 / 10, 2 * 0.01 / 20, 2 * 0.01 / 30]),
                               rtol=1e-15)
    np.testing.assert_array_equal(sys.Q, np.diag([1.0, 1.0, 2.0, 2.0, 3.0, 3.0]))
    np.testing.assert_array_equal(sys.W_z, np.zeros((3, 3)))     # c carries no noise
    # default x0: every vehicle starts on its target, C_i x_i(0) = H z_l(0) + d_i
    for i in range(3):
        np.testing.assert_allclose(C_I[i] @ sys.x0[2 * i:2 * i + 2], H_L @ Z0_L + D_I[i],
                                   atol=1e-14)


def test_no_offsets_means_no_offset_state():
    sys = fleet_system(generic_spec(offsets=False))
    assert sys.l == 2
    np.testing.assert_array_equal(sys.H, np.vstack([H_L] * 3))
    G = GAMMA
    Bz = np.zeros((6, 2))
    Bz[0:2] = 2.0 * G @ np.linalg.inv(C_I[0]) @ H_L
    np.testing.assert_allclose(sys.Bz, Bz, atol=1e-14)


def test_consensus_coupling_vanishes_on_the_formation():
    """Identical C (so x_0 = T z means the same in every vehicle): on the formation
    x_i = T z + delta_i every consensus and pinning term is zero, for any z."""
    C = np.array([[1.0, 1.0], [0.0, 2.0]])
    sys = fleet_system(generic_spec(C=[C, C, C]))
    Ablk = block_diag(*A_II)
    T = np.linalg.inv(C) @ H_L
    delta = np.concatenate([np.linalg.inv(C) @ d for d in D_I])
    rng = np.random.default_rng(0)
    for _ in range(5):
        zl = rng.normal(size=2)
        x = np.concatenate([T @ zl] * 3) + delta
        coupling = (sys.A - Ablk) @ x + sys.Bz @ np.concatenate([zl, [1.0]])
        np.testing.assert_allclose(coupling, 0.0, atol=1e-12)
        # and the tracking error is zero there
        np.testing.assert_allclose(sys.H @ np.concatenate([zl, [1.0]]) - sys.C @ x, 0.0, atol=1e-12)
    # off the formation it is not: move vehicle 2 by one unit
    x = np.concatenate([T @ Z0_L] * 3) + delta
    x[2] += 1.0
    assert np.abs((sys.A - Ablk) @ x + sys.Bz @ np.concatenate([Z0_L, [1.0]])).max() > 0.1


def _two_vehicles(edges, pinning):
    A1 = np.array([[-1.0, 0.5], [0.0, -2.0]])
    A2 = np.array([[-3.0, 0.0], [1.0, -1.0]])
    Gam = np.array([[1.0, 0.5], [0.0, 2.0]])            # has a zero entry
    spec = {"vehicles": [{"model": "generic", "params": {"A": A.tolist(), "B1": [[0.0], [1.0]],
                                                         "B2": [[1.0], [0.0]], "C": [[1.0, 0.0]]}}
                         for A in (A1, A2)],
            "graph": {"edges": edges, "pinning": pinning, "coupling": Gam.tolist()},
            "leader": {"kind": "explicit", "F": [[0.0]], "H": [[1.0]], "z0": [1.0]}}
    return fleet_system(spec).A, A1, A2, Gam


def test_laplacian_direction_edge_j_to_i_means_i_hears_j():
    a, g1, g2 = 0.7, 1.5, 0.25
    pins = [[1, g1], [2, g2]]                            # both pinned: both directions valid
    A12, A1, A2, Gam = _two_vehicles([[1, 2, a]], pins)  # 2 hears 1
    A21, *_ = _two_vehicles([[2, 1, a]], pins)           # 1 hears 2
    Z = np.zeros((2, 2))
    np.testing.assert_allclose(A12, np.block([[A1 - g1 * Gam, Z], [a * Gam, A2 - (a + g2) * Gam]]),
                               atol=1e-15)
    np.testing.assert_allclose(A21, np.block([[A1 - (a + g1) * Gam, a * Gam], [Z, A2 - g2 * Gam]]),
                               atol=1e-15)
    # the two differ by exactly [[a, -a], [a, -a]] kron Gamma: nothing else moves, and the
    # entries where Gamma is zero are equal
    diff = A12 - A21
    np.testing.assert_allclose(diff, np.kron([[a, -a], [a, -a]], Gam), atol=1e-15)
    assert np.count_nonzero(diff) == 4 * np.count_nonzero(Gam) == 12
    # pinned to the source only, the reversed edge leaves vehicle 2 unreachable
    _two_vehicles([[1, 2, a]], [[1, g1]])
    with pytest.raises(ModelError, match=r"vehicle 2 has no path from the leader"):
        _two_vehicles([[2, 1, a]], [[1, g1]])


# --------------------------------------------------------------------------------------
# resolve_fleet_spec
def _assert_same_system(a, b, rtol=0.0):
    for k in MATRICES:
        x, y = getattr(a, k), getattr(b, k)
        assert x.shape == y.shape, k
        np.testing.assert_allclose(x, y, rtol=rtol, atol=0, err_msg=k)
    assert a.noise_convention == b.noise_convention


def _formation4_raw_spec() -> dict:
    data = tomllib.loads((SCENARIO_DIR / "formation-4.toml").read_text())
    spec, _ = fleet_spec_from_dict(data)
    return spec


@pytest.mark.parametrize("make", [_formation4_raw_spec, generic_spec,
                                  lambda: generic_spec(offsets=False, coupling=None)],
                         ids=["formation-4", "generic", "generic-defaults"])
def test_resolve_fleet_spec_round_trip(make):
    spec = make()
    before = copy.deepcopy(spec)
    res = resolve_fleet_spec(spec)
    assert spec == before                       # the input is not modified
    json.dumps(res)                             # JSON-ready (it ships in the FMUs)
    # a time constant goes through -1/K: allow the last bit
    _assert_same_system(fleet_system(res), fleet_system(spec), rtol=1e-14)
    # idempotent, and every default is explicit
    _assert_same_system(fleet_system(resolve_fleet_spec(res)), fleet_system(res), rtol=1e-14)
    assert res["graph"]["coupling"] is not None
    for v in res["vehicles"]:
        assert {"x0", "offset", "params"} <= set(v)


# --------------------------------------------------------------------------------------
# formation-4: physics of the closed loop
@pytest.fixture(scope="module")
def formation():
    return load_scenario("formation-4")


@pytest.fixture(scope="module")
def noiseless_runs(formation):
    sys = formation.system.without_noise()
    return {tr: run_monolithic(sys, formation.h, "ideal", 0, formation.steps, tr)
            for tr in ("regulator", "lq")}


def _last(formation, seconds):
    return round((formation.T - seconds) / formation.h)


@pytest.mark.slow
def test_formation4_regulator_reaches_every_formation_target(formation, noiseless_runs):
    out = noiseless_runs["regulator"]
    info = formation.fleet.info(formation.system)
    k0 = _last(formation, 200.0)
    # position of each vehicle against leader position + offset, computed from the
    # states (not from e), then e = H z - C x must agree
    leader = out["z"][k0:] @ info.leader_output.T                          # (k, 3)
    errs = []
    for i in range(info.N):
        pos = out["x"][k0:, info.position_index[i]]
        errs.append(np.abs(leader + info.offsets[i] - pos).max())
    worst = max(errs)
    assert worst < 1e-2, f"regulator: worst position error over the last 200 s = {worst:.3g} m"
    assert np.abs(out["e"][k0:]).max() == pytest.approx(worst, rel=1e-9, abs=1e-12)
    # it really moved: the leader ran a lawnmower of 90 m legs, the vehicles followed
    assert np.ptp(out["x"][:, info.position_index[3, 0]]) > 80.0
    # and the vehicles started off formation
    assert np.abs(out["e"][0]).max() > 4.0


def test_formation4_regulator_residual_error_is_sampling(formation, noiseless_runs):
    """The few mm left are the zero-order hold: twice the step, twice the error."""
    sys = formation.system.without_noise()
    h2 = 2 * formation.h
    out2 = run_monolithic(sys, h2, "ideal", 0, round(formation.T / h2), "regulator")
    e1 = np.abs(noiseless_runs["regulator"]["e"][_last(formation, 200.0):]).max()
    e2 = np.abs(out2["e"][round(400.0 / h2):]).max()
    assert 1.8 < e2 / e1 < 2.2, f"h = 0.01 s: {e1:.3g} m, h = 0.02 s: {e2:.3g} m"


def test_formation4_lq_leaves_the_predicted_steady_error(formation, noiseless_runs):
    sys = formation.system.without_noise()
    out = noiseless_runs["lq"]
    k0 = _last(formation, 200.0)
    e = out["e"][k0:]
    measured = np.abs(e).max()
    assert measured > 0.5, f"lq: steady error only {measured:.3g} m"
    # theory: x -> Pi_cl v, v = [w; z], Pi_cl S = (A - B1 Kx) Pi_cl + [B2, Bz] - B1 [Kw, Kz]
    n, r = sys.n, sys.r
    Ks = tracking_law(sys, "lq").Ks
    Kx, Kv = Ks[:, :n], Ks[:, n:]
    S = block_diag(sys.K, sys.F)
    Pi = solve_sylvester(-(sys.A - sys.B1 @ Kx), S, np.hstack([sys.B2, sys.Bz]) - sys.B1 @ Kv)
    v = np.hstack([out["w"][k0:], out["z"][k0:]])
    e_ss = v @ (np.hstack([np.zeros((sys.p, r)), sys.H]) - sys.C @ Pi).T
    gap = np.abs(e - e_ss).max()
    assert gap < 6e-3, f"lq: measured {measured:.4g} m, theory {np.abs(e_ss).max():.4g} m, gap {gap:.3g} m"
    assert gap < 0.01 * measured


# --------------------------------------------------------------------------------------
# formation-4 co-simulated with the real FMUs
@pytest.fixture(scope="module")
def formation_fmus(formation, tmp_path_factory):
    return build(formation, tmp_path_factory.mktemp("fleet_fmus"))


@pytest.mark.slow
def test_formation4_cosimulation_equals_monolithic_for_both_tracking_modes(formation, formation_fmus):
    steps = 4000
    u = {}
    for tracking in ("lq", "regulator"):
        cfg = scenario_config(formation)
        cfg["tracking"] = tracking
        res = run_cosimulation(formation_fmus, cfg, mode="kalman", seed=0, steps=steps)
        ref = run_monolithic(formation.system, formation.h, "kalman", 0, steps, tracking)
        worst = max(float(np.max(np.abs(res.traces[k] - ref[k]))) for k in ref)
        assert worst < 1e-9, f"{tracking}: co-simulation vs monolithic max difference {worst:.3g}"
        u[tracking] = res.traces["u"]
    # the tracking parameter reached the controller FMU: the two laws differ
    assert np.abs(u["lq"] - u["regulator"]).max() > 1.0
