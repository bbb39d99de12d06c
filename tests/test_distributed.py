"""The distributed architecture's mathematics (controller_fmu.distributed and
orchestrator.analysis.distributed) against independent references: scipy's ODE solver and
matrix exponentials, python-control's lqr and dlyap, the vehicle library's leader_state_map
and state_offset, a stacked closed loop written here with Kronecker products, a per-vehicle
numpy simulation and a Monte-Carlo of the noisy sampled loop.

Conventions (plant_model.graph): an edge (j, i, a_ij) means vehicle i hears vehicle j;
(L x)_i = sum_j a_ij (x_i - x_j); G = diag(a_i0).
"""
from __future__ import annotations

import tomllib

import control
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm, solve_discrete_are, solve_discrete_lyapunov

from controller_fmu.distributed import (
    check_observer_gain,
    check_sampled_observer,
    cohesion_input,
    consensus_eigenvalues,
    control_input,
    coupling_force_gain,
    design_vehicle_law,
    graph_from_slots,
    innovation,
    min_observer_gain,
    regulation_error,
    sampled_observer,
    sampled_observer_gain_range,
)
from orchestrator.analysis.distributed import (
    Agent,
    agents_from_fleet_spec,
    design_laws,
    distributed_closed_loop,
)
from orchestrator.analysis.distributed_verdict import predict_cost, stability_verdict
from orchestrator.scenario import SCENARIO_DIR
from orchestrator.scenario.fleet import fleet_spec_from_dict
from plant_model.graph import communication_graph
from plant_model.leader import circle, lawnmower, straight
from plant_model.linalg_checks import ModelError
from plant_model.vehicle_targets import leader_state_map, state_offset
from plant_model.vehicles import remus100


# --------------------------------------------------------------------------------------
# graphs and data
def chain_graph():
    """0 -> 1 -> 2 -> 3 -> 4 with distinct weights: L + G lower bidiagonal, diagonalizable."""
    return communication_graph(4, [(1, 2, 2.0), (2, 3, 0.5), (3, 4, 1.5)], {1: 1.0})


def formation4_spec():
    data = tomllib.loads((SCENARIO_DIR / "formation-4.toml").read_text())
    return fleet_spec_from_dict(data)[0]


def formation4_graph():
    spec = formation4_spec()
    g = spec["graph"]
    return communication_graph(4, g["edges"], g["pinning"])


def random_graph(N=6, seed=3):
    """A random spanning tree from the leader plus random extra edges (cycles included)."""
    rng = np.random.default_rng(seed)
    edges = {}
    for i in range(2, N + 1):
        edges[(int(rng.integers(1, i)), i)] = float(rng.uniform(0.5, 2.0))
    while len(edges) < 2 * N:
        j, i = (int(v) for v in rng.integers(1, N + 1, size=2))
        if i != j and (j, i) not in edges:
            edges[(j, i)] = float(rng.uniform(0.5, 2.0))
    return communication_graph(N, [(j, i, a) for (j, i), a in edges.items()],
                               {1: 1.0, 4: 0.7})


GRAPHS = {"chain": chain_graph, "formation-4": formation4_graph, "random": random_graph}


def remus_agent(offset=(0.0, 0.0, 0.0), tau=30.0, sigma=0.0, W_x=0.0, V_y=0.0, R=0.01):
    m = remus100(cruise_speed=1.5)
    return Agent(A=m.A, B=m.B1, C=m.C, E=m.B2, Kw=-np.eye(3) / tau, Q=np.eye(3),
                 R=R * np.eye(3), W_x=W_x * np.eye(6), W_w=(2 * sigma**2 / tau) * np.eye(3),
                 V_y=V_y * np.eye(3), offset=np.asarray(offset, float), x0=np.zeros(6),
                 w0=np.zeros(3))


def zoh_expm(A, B, h):
    """Independent ZOH: expm of [[A, B], [0, 0]] h."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = expm(M * h)
    return E[:n, :n], E[:n, n:]


# --------------------------------------------------------------------------------------
# 1. the distributed observer
def test_continuous_observer_decays_at_the_predicted_rate():
    graph = random_graph()
    LG = graph.consensus_matrix()
    path = circle(radius=50.0, speed=1.5)          # marginally stable F: 0, 0, 0, +-0.03j
    F, l_ = path.F, path.F.shape[0]
    assert min_observer_gain(F, LG) == 0.0         # any mu > 0 works
    mu = 2.0
    rate = check_observer_gain(F, LG, mu)
    lam = np.linalg.eigvals(LG)
    assert rate == pytest.approx(-mu * lam.real.min(), rel=1e-9)
    Adj = graph.adjacency()
    g = np.diag(graph.pinning_matrix())
    N = graph.N

    def rhs(t, y):                                 # the observer as each vehicle runs it
        v, eta = y[:l_], y[l_:].reshape(N, l_)
        d = np.empty_like(eta)
        for i in range(N):
            r = sum(Adj[i, j] * (eta[j] - eta[i]) for j in range(N)) + g[i] * (v - eta[i])
            d[i] = F @ eta[i] + mu * r
        return np.concatenate([F @ v, d.ravel()])

    rng = np.random.default_rng(0)
    y0 = np.concatenate([path.z0, (path.z0 + rng.normal(0, 10, (N, l_))).ravel()])
    T = 40.0
    t = np.linspace(0, T, 401)
    sol = solve_ivp(rhs, (0, T), y0, t_eval=t, rtol=1e-11, atol=1e-12, method="DOP853")
    v = sol.y[:l_]
    err = np.linalg.norm(sol.y[l_:].reshape(N, l_, -1) - v[None], axis=(0, 1))
    slope = np.polyfit(t[200:], np.log(err[200:]), 1)[0]
    assert rate == pytest.approx(-0.3646, abs=1e-4)     # -mu * 0.1823, the slowest lambda
    assert slope == pytest.approx(rate, rel=0.05)
    assert err[-1] < 1e-4 * err[0]


def test_observer_gain_too_small_for_an_unstable_leader_is_refused():
    graph = chain_graph()
    LG = graph.consensus_matrix()
    F = np.array([[0.2, 1.0], [-1.0, 0.2]])        # growing spiral, Re f = 0.2
    lam_min = np.linalg.eigvals(LG).real.min()     # 0.5 (vehicle 3's weight)
    mu_min = min_observer_gain(F, LG)
    assert mu_min == pytest.approx(0.2 / lam_min)
    with pytest.raises(ModelError, match=r"at eigenvalue 0\.5 of L \+ G.*need mu > 0\.4"):
        check_observer_gain(F, LG, 0.9 * mu_min)
    assert check_observer_gain(F, LG, 1.1 * mu_min) < 0.0
    # the stacked error with scipy's expm: grows below mu_min, decays above
    for mu, grows in ((0.9 * mu_min, True), (1.1 * mu_min, False)):
        Aobs = np.kron(np.eye(4), F) - mu * np.kron(LG, np.eye(2))
        e = np.linalg.norm(expm(Aobs * 400.0) @ np.ones(8))    # rate +-0.02 1/s
        assert (e > 100.0) if grows else (e < 0.01)


def test_sampled_observer_is_the_held_innovation_solution_and_its_gain_range():
    path = lawnmower(90.0, 20.0, 1.5, 3, (0.0, 0.0, 20.0))
    F, l_ = path.F, path.F.shape[0]
    h, mu = 0.01, 2.0
    obs = sampled_observer(F, h, mu)
    rng = np.random.default_rng(1)
    eta, r = rng.normal(size=l_), rng.normal(size=l_)
    # one step equals the exact solution of eta' = F eta + mu r with r held
    sol = solve_ivp(lambda t, y: F @ y + mu * r, (0, h), eta, rtol=1e-12, atol=1e-14)
    assert np.allclose(obs.step(eta, r), sol.y[:, -1], atol=1e-11)
    # the per-vehicle form Ad_i eta + B_nbr (sum a_ij eta_j + a_i0 v)
    nbrs, w, a0, v = rng.normal(size=(2, l_)), np.array([0.5, 1.5]), 0.7, rng.normal(size=l_)
    Ad_i, B = obs.vehicle_matrices(w.sum() + a0)
    assert np.allclose(obs.step(eta, innovation(eta, nbrs, w, a0, v)),
                       Ad_i @ eta + B @ (w @ nbrs + a0 * v), atol=1e-12)
    # the leader is an exact fixed point: all eta_j = v[k] gives eta_i[k+1] = v[k+1]
    v = path.z0
    assert np.allclose(obs.step(v, innovation(v, [v, v], w, a0, v)), expm(F * h) @ v,
                       atol=1e-12)
    # the gain interval against the stacked sampled error built with kron
    graph = random_graph()
    LG = graph.consensus_matrix()
    lo, hi = sampled_observer_gain_range(F, LG, h)
    assert lo == 0.0 and np.isfinite(hi)
    Phi = expm(F * h)
    Gam = zoh_expm(F, np.eye(l_), h)[1]

    def rho(mu_):
        M = np.kron(np.eye(graph.N), Phi) - mu_ * np.kron(LG, Gam)
        return np.max(np.abs(np.linalg.eigvals(M)))

    assert rho(0.99 * hi) < 1.0 < rho(1.01 * hi)
    assert check_sampled_observer(F, LG, h, 0.99 * hi) == pytest.approx(rho(0.99 * hi), abs=1e-6)
    lam = consensus_eigenvalues(LG)
    worst = lam[np.argmax(np.abs(lam) ** 2 / lam.real)]   # the smallest 2 Re lam / |lam|^2 h
    with pytest.raises(ModelError, match=f"at eigenvalue {worst.real:.6g}.*spectral radius"):
        check_sampled_observer(F, LG, h, 1.01 * hi)


# --------------------------------------------------------------------------------------
# 2. regulator equations and the LQ gain
@pytest.mark.parametrize("path", [lawnmower(90.0, 20.0, 1.5, 3, (0.0, 0.0, 20.0)),
                                  circle(150.0, 1.5, (150.0, 0.0, 20.0))],
                         ids=["lawnmower", "circle"])
def test_regulator_equations_with_offset_and_current(path):
    m = remus100(cruise_speed=1.5)
    F, H, Kw, d, h = path.F, path.H, -np.eye(3) / 30.0, np.array([-10.0, 20.0, 0.0]), 0.01
    law = design_vehicle_law(m.A, m.B1, m.C, np.eye(3), 0.01 * np.eye(3), F, H, d, m.B2, Kw)
    A, B, C, E = m.A, m.B1, m.C, m.B2
    assert np.abs(law.X @ F - A @ law.X - B @ law.U).max() < 1e-10
    assert np.abs(C @ law.X - H).max() < 1e-10
    assert np.abs(law.Xw @ Kw - A @ law.Xw - B @ law.Uw - E).max() < 1e-10
    assert np.abs(C @ law.Xw).max() < 1e-10
    assert np.abs(A @ law.xc + B @ law.uc).max() < 1e-10
    assert np.abs(C @ law.xc - d).max() < 1e-10
    # remus100: X is the leader's position and velocity, the offset a shift at rest
    assert np.allclose(law.X, leader_state_map(m, H, F), atol=1e-10)
    assert np.allclose(law.xc, state_offset(m, d), atol=1e-12)
    assert np.allclose(law.Uw, -np.diag(m.parameters["damping"]), atol=1e-9)  # cancels the drag
    # python-control's LQR as the reference for Kx
    K_ref, _, _ = control.lqr(A, B, C.T @ C, 0.01 * np.eye(3))
    assert np.allclose(law.Kx, K_ref, rtol=1e-8, atol=1e-8)
    # the sampled form against the ZOH model computed here
    sl = design_vehicle_law(A, B, C, np.eye(3), 0.01 * np.eye(3), F, H, d, E, Kw,
                            regulator="sampled", h=h)
    Ac = np.block([[A, E], [np.zeros((3, 6)), Kw]])
    Ad_, Bd_ = zoh_expm(Ac, np.vstack([B, np.zeros((3, 3))]), h)
    Ad, Adw, Bd, Phi_w = Ad_[:6, :6], Ad_[:6, 6:], Bd_[:6], Ad_[6:, 6:]
    Phi = expm(F * h)
    assert np.abs(sl.X @ Phi - Ad @ sl.X - Bd @ sl.U).max() < 1e-10
    assert np.abs(C @ sl.X - H).max() < 1e-10
    assert np.abs(sl.Xw @ Phi_w - Ad @ sl.Xw - Bd @ sl.Uw - Adw).max() < 1e-10
    assert np.abs(sl.xc - law.xc).max() < 1e-10          # an equilibrium is one in both
    assert 0 < np.abs(sl.U - law.U).max() < 1e-2 * np.abs(law.U).max() + 1e-6   # O(h) apart


def test_transmission_zero_at_an_eigenvalue_of_the_leader_is_refused():
    w = 0.5                                             # G(s) = (s^2 + w^2) / (s + 1)^3
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, -3.0, -3.0]])
    B = np.array([[0.0], [0.0], [1.0]])
    C = np.array([[w * w, 0.0, 1.0]])
    F = np.array([[0.0, -w], [w, 0.0]])                # an oscillator at the zero's frequency
    H = np.array([[1.0, 0.0]])
    with pytest.raises(ModelError, match=r"vehicle 2: .*eigenvalue 0\+0\.5j.*F \(leader\).*"
                                         r"transmission zero"):
        design_vehicle_law(A, B, C, np.eye(1), np.eye(1), F, H, where="vehicle 2: ")
    with pytest.raises(ModelError, match=r"eigenvalue 0\+0\.5j of the exosystem F \(leader\)"):
        design_vehicle_law(A, B, C, np.eye(1), np.eye(1), F, H, regulator="sampled", h=0.01)
    # a sampling zero: the ZOH of a double integrator has its zero at exactly -1, i.e. at
    # exp(f h) for f = j pi / h (an oscillator at the Nyquist frequency)
    h = 0.1
    Fn = np.array([[0.0, -np.pi / h], [np.pi / h, 0.0]])
    with pytest.raises(ModelError, match=r"sampled regulator equations have no solution: at "
                                         r"eigenvalue 0[+-]31\.4159j of the leader's F"):
        design_vehicle_law(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]),
                           np.array([[1.0, 0.0]]), np.eye(1), np.eye(1), Fn, H,
                           regulator="sampled", h=h)
    # away from the zero it is solvable
    F2 = np.array([[0.0, -2 * w], [2 * w, 0.0]])
    law = design_vehicle_law(A, B, C, np.eye(1), np.eye(1), F2, H)
    assert np.abs(law.X @ F2 - A @ law.X - B @ law.U).max() < 1e-10


def test_unstabilizable_vehicle_is_refused_naming_the_mode():
    A = np.diag([0.3, -1.0])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 1.0]])
    with pytest.raises(ModelError, match=r"vehicle 5: \(A, B1\) is not stabilizable: the "
                                         r"mode\(s\) 0\.3 of A"):
        design_vehicle_law(A, B, C, np.eye(1), np.eye(1), np.zeros((1, 1)), np.ones((1, 1)),
                           where="vehicle 5: ")


# --------------------------------------------------------------------------------------
# 3. the sampled closed loop: per-eigenvalue verdict against a stacked loop built here
def kron_error_loop(law, agent, LG, F, h, mu, c):
    """The error part of the stacked sampled loop (ideal estimates, v = 0), with kron:
    per vehicle s_i = [x_i; w_i], then all eta_i."""
    N = LG.shape[0]
    p, r = agent.A.shape[0], agent.E.shape[1]
    Ac = np.block([[agent.A, agent.E], [np.zeros((r, p)), agent.Kw]])
    Ad, Bd = zoh_expm(Ac, np.vstack([agent.B, np.zeros((r, agent.B.shape[1]))]), h)
    Phi = expm(F * h)
    GamF = zoh_expm(F, np.eye(F.shape[0]), h)[1]
    T = np.hstack([np.eye(p), -law.Xw])                 # eps = T s - X eta
    Ks = np.hstack([-law.Kx, law.Uw + law.Kx @ law.Xw])  # u = Ks s + Keta eta + cohesion
    Keta = law.U + law.Kx @ law.X
    IN = np.eye(N)
    Sss = np.kron(IN, Ad + Bd @ Ks) - c * np.kron(LG, Bd @ law.Kx @ T)
    Sse = np.kron(IN, Bd @ Keta) + c * np.kron(LG, Bd @ law.Kx @ law.X)
    See = np.kron(IN, Phi) - mu * np.kron(LG, GamF)
    return np.block([[Sss, Sse], [np.zeros((See.shape[0], Sss.shape[1])), See]])


@pytest.mark.parametrize("name", list(GRAPHS))
def test_decoupled_verdict_equals_the_stacked_spectral_radius(name):
    graph = GRAPHS[name]()
    LG = graph.consensus_matrix()
    path = straight(1.5, 30.0, (0.0, 0.0, 20.0))
    h = 0.05
    agents = [remus_agent(offset=(3.0 * i, -2.0 * i, 0.0)) for i in range(graph.N)]
    laws = design_laws(agents, path.F, path.H)
    lam = consensus_eigenvalues(LG)
    # the cohesion gain at which the worst block reaches the unit circle, by bisection on
    # the block of the eigenvalue with the largest modulus (a stacked loop check follows)
    cases = [(1.0, 0.5, True)]
    lo_c, hi_c = 0.0, 200.0
    for _ in range(40):
        mid = 0.5 * (lo_c + hi_c)
        M = kron_error_loop(laws[0], agents[0], LG, path.F, h, 1.0, mid)
        lo_c, hi_c = (mid, hi_c) if np.max(np.abs(np.linalg.eigvals(M))) < 1 else (lo_c, mid)
    cases += [(1.0, 1.2 * hi_c, False), (1.1 * sampled_observer_gain_range(
        path.F, LG, h)[1], 0.0, False)]
    for mu, c, stable in cases:
        obs = sampled_observer(path.F, h, mu)
        loop = distributed_closed_loop(agents, laws, graph, obs, path.H, cohesion=c)
        verdict = stability_verdict(loop)
        M = kron_error_loop(laws[0], agents[0], LG, path.F, h, mu, c)
        ev = np.linalg.eigvals(M)
        rho = np.max(np.abs(ev))
        assert verdict.identical and len(verdict.blocks) == graph.N
        # formation-4's L + G is one Jordan chain (eigenvalue 1, 4 times): the stacked
        # eigenvalues computed here are then only good to about eps^(1/4)
        tol = 1e-4 if name == "formation-4" else 1e-7
        assert verdict.spectral_radius == pytest.approx(rho, abs=tol)
        assert verdict.stacked_spectral_radius == pytest.approx(rho, abs=tol)
        assert verdict.stable == stable == (rho < 1)
        # the module's stacked error part has the same eigenvalues as the kron loop
        R = ~loop.deterministic
        ev2 = np.linalg.eigvals(loop.Phi[np.ix_(R, R)])
        dist = np.abs(ev[:, None] - ev2[None, :])
        assert ev.size == ev2.size and dist.min(0).max() < 10 * tol and dist.min(1).max() < 10 * tol
        if not stable:
            bad = max(verdict.blocks, key=lambda b: b[1])[0]
            assert any(abs(bad - x) < 1e-9 for x in lam)
            with pytest.raises(ModelError, match=rf"at eigenvalue {bad.real:.6g}.* of L \+ G "
                                                 r"the vehicle block has spectral radius"):
                stability_verdict(loop, check=True)
    assert verdict.observer_mu_min == 0.0 and "every c >= 0" in verdict.cohesion_bound


# --------------------------------------------------------------------------------------
# 4. a monolithic per-vehicle simulation of formation-4
def simulate_per_vehicle(agents, laws, graph, path, h, mu, c, steps):
    """Noise-free, ideal estimates: each vehicle runs the per-vehicle functions."""
    N = graph.N
    Adj, g = graph.adjacency(), np.diag(graph.pinning_matrix())
    obs = sampled_observer(path.F, h, mu)
    Phi = expm(path.F * h)
    plants = []
    for a in agents:
        p, r = a.A.shape[0], a.E.shape[1]
        Ac = np.block([[a.A, a.E], [np.zeros((r, p)), a.Kw]])
        plants.append(zoh_expm(Ac, np.vstack([a.B, np.zeros((r, a.B.shape[1]))]), h))
    s = [np.concatenate([a.x0, a.w0]) for a in agents]
    eta = [np.zeros(path.F.shape[0]) for _ in agents]
    v = path.z0.copy()
    errs = np.zeros((steps, N, 3))
    for k in range(steps):
        for i in range(N):
            errs[k, i] = path.H @ v + agents[i].offset - agents[i].C @ s[i][:6]
        eps = [regulation_error(laws[i], s[i][:6], s[i][6:], eta[i]) for i in range(N)]
        nb = [np.flatnonzero(Adj[i]) for i in range(N)]
        u = [control_input(laws[i], s[i][:6], s[i][6:], eta[i],
                           cohesion_input(laws[i], c, eps[i], [eps[j] for j in nb[i]],
                                          Adj[i, nb[i]], g[i]))
             for i in range(N)]
        r = [innovation(eta[i], [eta[j] for j in nb[i]], Adj[i, nb[i]], g[i], v)
             for i in range(N)]
        for i in range(N):
            s[i] = plants[i][0] @ s[i] + plants[i][1] @ u[i]
            eta[i] = obs.step(eta[i], r[i])
        v = Phi @ v
    return errs, s, eta, v


@pytest.mark.slow
def test_formation4_outputs_converge_to_leader_plus_offset():
    spec = formation4_spec()
    agents, graph, leader = agents_from_fleet_spec(spec)
    path = lawnmower(90.0, 20.0, 1.5, 3, (0.0, 0.0, 20.0))
    assert np.allclose(path.F, leader["F"]) and np.allclose(path.z0, leader["z0"])
    h, mu, c, steps = 0.01, 1.0, 0.5, 10000
    laws = design_laws(agents, path.F, path.H, regulator="sampled", h=h)
    errs, s, eta, v = simulate_per_vehicle(agents, laws, graph, path, h, mu, c, steps)
    assert np.abs(errs[0]).max() > 5.0
    assert np.abs(errs[-500:]).max() < 1e-6               # zero steady error at the samples
    # the stacked loop's noise-free motion equals the per-vehicle simulation
    obs = sampled_observer(path.F, h, mu)
    loop = distributed_closed_loop(agents, laws, graph, obs, path.H, cohesion=c)
    X = loop.initial_state(path.z0, [a.x0 for a in agents], [a.w0 for a in agents])
    X = np.linalg.matrix_power(loop.Phi, steps) @ X
    assert np.allclose(X[loop.index["v"][0]], v, atol=1e-8)
    for i in range(graph.N):
        assert np.allclose(X[loop.index["s"][i]], s[i], atol=1e-7)
        assert np.allclose(X[loop.index["eta"][i]], eta[i], atol=1e-8)
    # the continuous regulator leaves an O(h) steady error on the survey's turns
    laws_c = design_laws(agents, path.F, path.H)
    errs_c = simulate_per_vehicle(agents, laws_c, graph, path, h, mu, 0.0, 8000)[0]
    assert 1e-6 < np.abs(errs_c[-1000:]).max() < 1e-2


# --------------------------------------------------------------------------------------
# 5. the Lyapunov prediction against a Monte-Carlo of the same sampled loop
def test_predicted_cost_rate_matches_monte_carlo():
    graph = communication_graph(3, [(1, 2, 1.0), (2, 3, 0.8), (3, 2, 0.4)], {1: 1.0})
    path = straight(0.0)                                 # at rest: the cost is the noise's
    h, mu, c = 0.05, 1.0, 0.5
    agents = [remus_agent(offset=(5.0 * i, 0, 0), tau=5.0, sigma=0.05, W_x=1e-3, V_y=0.05)
              for i in range(3)]
    laws = design_laws(agents, path.F, path.H)
    obs = sampled_observer(path.F, h, mu)
    loop = distributed_closed_loop(agents, laws, graph, obs, path.H, cohesion=c,
                                   estimator="kalman")
    k0, K = 300, 600
    X0 = loop.initial_state(np.zeros(6), [a.xc for a in laws], [np.zeros(3)] * 3,
                            [np.zeros(6)] * 3)
    pred = predict_cost(loop, (k0, K), X0, transient=True)
    stat = predict_cost(loop)
    # python-control's dlyap as the reference for the stationary covariance
    R = ~loop.deterministic
    PhiR, GR = loop.Phi[np.ix_(R, R)], loop.Gam[R]
    Q = GR @ loop.W @ GR.T
    assert np.allclose(control.dlyap(PhiR, Q), solve_discrete_lyapunov(PhiR, Q), atol=1e-10)

    # Monte-Carlo, written per vehicle (own Kalman filter from scipy's DARE)
    runs = 1500
    rng = np.random.default_rng(7)
    Adj, g = graph.adjacency(), np.diag(graph.pinning_matrix())
    Ac = np.block([[agents[0].A, agents[0].E], [np.zeros((3, 6)), agents[0].Kw]])
    Ad, Bd = zoh_expm(Ac, np.vstack([agents[0].B, np.zeros((3, 3))]), h)
    from plant_model.discretization import van_loan
    Qd = van_loan(Ac, np.diag([1e-3] * 6 + [2 * 0.05**2 / 5.0] * 3), h)
    Rd = 0.05 / h * np.eye(3)
    M = np.hstack([np.eye(3), np.zeros((3, 6))])
    P = solve_discrete_are(Ad.T, M.T, Qd, Rd)
    L = P @ M.T @ np.linalg.inv(M @ P @ M.T + Rd)
    Lq = np.linalg.cholesky(Qd + 1e-15 * np.eye(9))
    Lr = np.linalg.cholesky(Rd)
    s = [np.tile(np.concatenate([law.xc, np.zeros(3)])[:, None], runs) for law in laws]
    q = [si.copy() for si in s]
    eta = [np.zeros((6, runs)) for _ in range(3)]
    total = np.zeros(runs)
    for k in range(K):
        y = [M @ s[i] + Lr @ rng.standard_normal((3, runs)) for i in range(3)]
        est = [q[i] + L @ (y[i] - M @ q[i]) for i in range(3)]
        eps = [est[i][:6] - laws[i].Xw @ est[i][6:] - laws[i].X @ eta[i] - laws[i].xc[:, None]
               for i in range(3)]
        u = []
        for i in range(3):
            rel = sum(Adj[i, j] * (eps[j] - eps[i]) for j in range(3)) - g[i] * eps[i]
            u.append(laws[i].U @ eta[i] + laws[i].Uw @ est[i][6:] + laws[i].uc[:, None]
                     - laws[i].Kx @ eps[i] + c * laws[i].Kx @ rel)
        if k >= k0:
            for i in range(3):
                e = agents[i].offset[:, None] - s[i][:3]
                total += (e * e).sum(0) + 0.01 * (u[i] * u[i]).sum(0)
        for i in range(3):
            s[i] = Ad @ s[i] + Bd @ u[i] + Lq @ rng.standard_normal((9, runs))
            q[i] = Ad @ est[i] + Bd @ u[i]
    per_run = total / (K - k0)
    mc, se = per_run.mean(), per_run.std(ddof=1) / np.sqrt(runs)
    assert abs(mc - pred.cost_rate) < 4 * se
    assert se < 0.02 * mc
    assert stat.cost_rate == pytest.approx(pred.cost_rate, rel=0.05)   # near stationary


# --------------------------------------------------------------------------------------
# 6. bad input: one line each
def test_neighbour_slots_and_graph_errors():
    nb = np.array([[0, 0], [1, 0], [2, 7]])
    w = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.5]])
    with pytest.raises(ModelError, match=r"^vehicle 3: neighbour slot 2 is wired to vehicle 7, "
                                         r"which does not exist \(vehicles are 1\.\.3\)$"):
        graph_from_slots(3, nb, w, [1.0, 0.0, 0.0])
    nb[2, 1] = 1
    g = graph_from_slots(3, nb, w, [1.0, 0.0, 0.0])
    assert g.edges == ((1, 2, 1.0), (1, 3, 0.5), (2, 3, 1.0))
    with pytest.raises(ModelError, match=r"vehicles 2, 3 have no path from the leader"):
        graph_from_slots(3, [[0], [3], [2]], [[0.0], [1.0], [1.0]], [1.0, 0.0, 0.0])
    with pytest.raises(ModelError, match=r"no positive real part"):
        consensus_eigenvalues(np.array([[1.0, 0.0], [0.0, 0.0]]))


def test_coupling_through_the_actuators():
    m = remus100(cruise_speed=1.5)
    Gam = np.array(formation4_spec()["graph"]["coupling"])
    Kc = coupling_force_gain(m.B1, Gam, m.state_names)
    assert np.allclose(m.B1 @ Kc, Gam, atol=1e-14)
    M = np.array(m.parameters["total_mass"])
    assert np.allclose(Kc, np.hstack([np.diag(0.02 * M), np.diag(0.2 * M)]))
    with pytest.raises(ModelError, match=r"its rows for n, e, d cannot be produced by any "
                                         r"force"):
        coupling_force_gain(m.B1, np.eye(6), m.state_names)
