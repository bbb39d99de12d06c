"""orchestrator.analysis.acoustic (message_form, loop, prediction): the per-vehicle loop
over acoustic links, its exact second moment, mean-square stability and critical loss."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.linalg import solve_discrete_lyapunov

from controller_fmu.regulator import tracking_law
from controller_fmu.vehicle_law import centralized_rows
from estimator_fmu.registry import make_estimator
from orchestrator.analysis.acoustic.cycle import _Compiler
from orchestrator.analysis.acoustic.loop import NetworkedLoop
from orchestrator.analysis.acoustic.message_form import (
    centralized_message_form,
    distributed_message_form,
    perfect_links,
)
from orchestrator.analysis.acoustic.prediction import predict_window
from orchestrator.analysis.acoustic.stability import (
    critical_loss,
    frozen_radius,
    ms_spectral_radius,
    ms_stable,
)
from orchestrator.analysis.per_vehicle import (
    distributed_initial_state,
    distributed_loop_of,
    distributed_noise,
)
from orchestrator.analysis.prediction import method_predictions
from orchestrator.scenario import load_scenario
from plant_model.acoustic.links import LinkChannel, check_link, link_key
from plant_model.discretization import discretize

DATA = __import__("pathlib").Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def f4():
    return load_scenario("formation-4").with_run(h=0.05)


def _H_offsets(sc):
    H = sc.fleet.leader.H
    return H, sc.fleet.offsets


def _centralized(sc, mode):
    loop = distributed_loop_of(sc, mode, "regulator", sc.distributed)
    N, p = len(loop.sampled), loop.laws[0].Kx.shape[1]
    r, m = loop.sampled[0].Ad.shape[0] - p, loop.sampled[0].Bd.shape[1]
    rows = centralized_rows(tracking_law(sc.system, "regulator").Ks, N, p, r, m,
                            loop.observer.Phi.shape[0])
    return loop, centralized_message_form(loop, rows)


@pytest.mark.parametrize("mode", ["ideal", "kalman"])
@pytest.mark.parametrize("cohesion", [0.0, 0.5])
def test_perfect_links_give_back_the_distributed_loop(f4, mode, cohesion):
    loop = distributed_loop_of(f4, mode, "regulator",
                               dataclasses.replace(f4.distributed, cohesion=cohesion))
    form = distributed_message_form(loop, *_H_offsets(f4))
    for got, want in zip(perfect_links(form), (loop.Phi, loop.Gam, loop.Gx, loop.Geta)):
        assert np.allclose(got, want, rtol=0, atol=1e-12 * max(1.0, np.abs(want).max()))
    assert len(form.links) == 5                      # 4 edges and the leader to vehicle 1
    assert [f for f, _ in form.senders[1].fields] == (["eta", "eps"] if cohesion else ["eta"])


@pytest.mark.parametrize("mode", ["ideal", "kalman"])
def test_perfect_links_give_back_the_stacked_centralized_cost(f4, mode):
    """The centralized per-vehicle loop cut at its messages, closed again, has the stacked
    deployment's stationary cost (an independent construction: the stacked estimator)."""
    _, form = _centralized(f4, mode)
    Phi, Gam, Gx, Geta = perfect_links(form)
    R = ~form.deterministic
    S = solve_discrete_lyapunov(Phi[np.ix_(R, R)], Gam[R] @ form.W @ Gam[R].T)
    Sig = np.zeros_like(Phi)
    Sig[np.ix_(R, R)] = S
    cost = (np.trace(form.Qc @ form.Ce @ Sig @ form.Ce.T)
            + np.trace(form.Rc @ (Gx @ Sig @ Gx.T + Geta @ form.W @ Geta.T)))
    model = discretize(f4.system, f4.h)
    want = method_predictions(f4, model, make_estimator(f4.system, model, mode),
                              tracking_law(f4.system, "regulator").Ks)[0].cost_rate
    assert cost == pytest.approx(want, rel=1e-9)
    assert len(form.links) == 16                     # 4 x 3 pairs and the leader to all


def _channel_reference(form, net, X0, zeta, seed, receiver, timings, schedule=None):
    """The cut loop stepped with one LinkChannel per link (plant_model.acoustic.links); a link
    down in the schedule loses what it sends."""
    ch = {k: LinkChannel(timings[k], form.h, seed, link_key(*k), form.senders[k[0]].Cm @ X0,
                         form.senders[k[0]].M(receiver)) for k in form.links}
    X, out = X0.copy(), []
    for k in range(zeta.shape[0]):
        R = {key: c.rx for key, c in ch.items()}
        out.append(np.concatenate([X] + [R[key] for key in net.R]))
        msgs = {j: s.Cm @ X + s.Dm @ zeta[k] + sum((Cr @ R[lk] for lk, Cr in s.Cr.items()),
                                                   np.zeros(s.width))
                for j, s in form.senders.items()}
        X = form.Phi @ X + form.Gam @ zeta[k] + sum(lk.B @ R[key]
                                                    for key, lk in form.links.items())
        for key, c in ch.items():
            c.advance(k, msgs[key[0]], schedule is None or schedule.is_up(key, k))
    return np.array(out)


@pytest.mark.parametrize("architecture", ["distributed", "centralized"])
@pytest.mark.parametrize("receiver", ["hold", "propagate"])
def test_the_augmented_loop_is_the_links_stepped_one_by_one(f4, architecture, receiver):
    """Held and in-flight messages as states (shift registers, one per sender and timing)
    reproduce LinkChannel objects stepped per link: latency 0.35 s over periods of 0.2 s
    (two in flight), offsets, 30 % loss."""
    if architecture == "distributed":
        loop = distributed_loop_of(f4, "kalman", "regulator",
                                   dataclasses.replace(f4.distributed, cohesion=0.5))
        form = distributed_message_form(loop, *_H_offsets(f4))
    else:
        loop, form = _centralized(f4, "kalman")
    X0 = form.state_of(distributed_initial_state(f4, loop))
    timings = {k: check_link(str(k), 0.35, 0.2 if k[0] == 2 else 0.5, 0.3,
                             0.1 if k[0] == 1 else 0.0) for k in form.links}
    net = NetworkedLoop(form, timings, receiver)
    zeta = np.random.default_rng(0).standard_normal((160, form.Gam.shape[1])) * 0.01
    Z = net.simulate(net.initial_state(X0), zeta, seed=3)
    order = np.r_[np.arange(form.Phi.shape[0]),
                  np.concatenate([np.arange(sl.start, sl.stop) for sl in net.R.values()])]
    ref = _channel_reference(form, net, X0, zeta, 3, receiver, timings)
    assert np.allclose(Z[:, order], ref, rtol=0, atol=1e-11 * np.abs(ref).max())
    assert max(len(g.slots) for g in net.groups.values()) == 2


#: formation-4's graph in two halves, 10 s each: neither reaches every vehicle, the union does
HALVES = {"schedule": [{"t": 0.0, "edges": [["leader", 1], [1, 2], [2, 4]]},
                       {"t": 10.0, "edges": [["leader", 1], [1, 3], [3, 4]]}],
          "schedule_period": 20.0}


@pytest.mark.parametrize("architecture, receiver", [("distributed", "propagate"),
                                                    ("centralized", "hold")])
def test_a_schedule_switches_the_links_as_link_channels_told_so(f4, architecture, receiver):
    """Links switched on and off by a periodic schedule (a message sent while its link is
    down is lost): the augmented loop equals LinkChannels stepped per link, and a down
    link's messages never arrive."""
    from plant_model.acoustic.schedule import resolve_schedule
    if architecture == "distributed":
        loop = distributed_loop_of(f4, "kalman", "regulator", f4.distributed)
        form = distributed_message_form(loop, *_H_offsets(f4))
        table = {"schedule": [{"t": 0.0, "edges": [["leader", 1], [1, 2], [2, 4]]},
                              {"t": 1.5, "down": [[1, 2], [1, 3]]}], "schedule_period": 3.5}
    else:
        loop, form = _centralized(f4, "kalman")
        table = {"schedule": [{"t": 0.0, "down": [[2, 1], [3, 4], ["leader", 2]]},
                              {"t": 2.0, "edges": [["leader", 1], [1, 2], [4, 3]]}],
                 "schedule_period": 4.5}
    X0 = form.state_of(distributed_initial_state(f4, loop))
    timings = {k: check_link(str(k), 0.35, 0.5, 0.2) for k in form.links}
    sched = resolve_schedule(table, form.links, f4.h, 4)
    net = NetworkedLoop(form, timings, receiver, sched)
    # the cycle: lcm(10 steps of messages, the schedule's 70 or 90 steps)
    assert net.period == np.lcm(10, round(table["schedule_period"] / f4.h))
    zeta = np.random.default_rng(1).standard_normal((400, form.Gam.shape[1])) * 0.01
    Z = net.simulate(net.initial_state(X0), zeta, seed=5)
    order = np.r_[np.arange(form.Phi.shape[0]),
                  np.concatenate([np.arange(sl.start, sl.stop) for sl in net.R.values()])]
    ref = _channel_reference(form, net, X0, zeta, 5, receiver, timings, sched)
    assert np.allclose(Z[:, order], ref, rtol=0, atol=1e-11 * np.abs(ref).max())
    never = [k for k in form.links if not any(sched.up[k])]
    assert never and all(np.all(net.ages(400, 5)[k] == np.arange(400) * f4.h) for k in never)


@pytest.mark.slow
def test_a_jointly_connected_schedule_predicted_and_simulated(f4):
    """formation-4 distributed over links of period 2 s, latency 1 s, loss 20 %, the graph
    switching between two halves every 10 s (neither reaches every vehicle, the union
    does): the exact expected cost over the window agrees with 16 simulated seeds, the
    radius over one 20 s period is below 1; propagating receivers lose almost nothing to
    the switching, holding ones more than double their cost."""
    from plant_model.acoustic.schedule import connectivity, resolve_schedule
    from plant_model.acoustic.settings import resolve_links
    sc = f4.with_run(T=100.0)
    loop = distributed_loop_of(sc, "kalman", "regulator", sc.distributed)
    form = distributed_message_form(loop, *_H_offsets(sc))
    timings = resolve_links(4, sc.fleet.edges, sc.fleet.pinning,
                            {"latency": 1.0, "period": 2.0, "loss": 0.2}, sc.h)
    sched = resolve_schedule(HALVES, timings, sc.h, 4)
    assert connectivity(sched, timings) == {"connected_graphs": [False, False],
                                            "jointly_connected": True}
    net = NetworkedLoop(form, timings, "propagate", sched)
    assert net.period * sc.h == pytest.approx(20.0)
    Z0, k0, K, pred = _prediction_agrees_with_seeds(sc, loop, net, form)
    # propagating receivers carry the noise-free leader's estimate across the gaps: the
    # switching costs under 0.1 % (only while the observers converge; 2e-12 from 150 s
    # on); holding receivers pay for every silent half period
    always = NetworkedLoop(form, timings, "propagate")
    assert predict_window(always, Z0, k0, K).cost_rate == pytest.approx(pred.cost_rate,
                                                                        rel=1e-3)
    held = [predict_window(NetworkedLoop(form, timings, "hold", s), Z0, k0, K).cost_rate
            for s in (None, sched)]
    assert held[1] > 2.0 * held[0]


@pytest.mark.slow
def test_joint_connectivity_is_not_sufficient():
    """The spiral leader (growth 0.05 1/s) heard for 2 s in every 20 s over links losing
    half the messages: every vehicle hears the leader's information in the union of the
    graphs, yet the second moment grows. The leader link's held message is reset with
    probability 0.5 once per period and otherwise drifts by exp(0.05 x 20) in magnitude, so
    the radius per period is 0.5 e^2 = 3.69: the prediction gives it, and 400 simulated
    loss sequences grow as the predicted second moment does."""
    from plant_model.acoustic.schedule import connectivity, resolve_schedule
    sc = load_scenario(DATA / "spiral-leader-network.toml")
    loop = distributed_loop_of(sc, "kalman", "regulator", sc.distributed)
    form = distributed_message_form(loop, *_H_offsets(sc))
    timings = {k: check_link(str(k), 1.0, 2.0, 0.5) for k in form.links}
    sched = resolve_schedule({"schedule": [{"t": 0.0, "down": []},
                                           {"t": 2.0, "down": [["leader", 1]]}],
                              "schedule_period": 20.0}, timings, sc.h, 4)
    assert connectivity(sched, timings)["jointly_connected"]
    net = NetworkedLoop(form, timings, "propagate", sched)
    assert ms_spectral_radius(net) == pytest.approx(0.5 * np.exp(2.0), rel=1e-6)
    assert ms_stable(net) is False
    Z0 = net.initial_state(form.state_of(distributed_initial_state(sc, loop)))
    Z0[net.deterministic] = 0.0                    # the error coordinates: no leader
    steps = 3 * net.period
    comp = _Compiler(net)
    X, _ = comp.apply(comp.plan(0, steps), np.outer(Z0, Z0), noise=False)
    zeta = np.zeros((steps + 1, form.Gam.shape[1]))
    sim = np.mean([np.sum(net.simulate(Z0, zeta, s)[-1] ** 2) for s in range(400)])
    assert np.trace(X) > 10.0 * (Z0 @ Z0)
    assert sim == pytest.approx(np.trace(X), rel=0.35)


def _mc_cost(sc, net, form, Z0, k0, K, seeds):
    out = []
    for seed in seeds:
        zeta = distributed_noise(sc, seed, K)
        Z = net.simulate(Z0, zeta, seed)
        e, u = Z @ net.Ce.T, Z @ net.Gx.T + zeta @ form.Geta.T
        J = np.einsum("ki,ij,kj->k", e, form.Qc, e) + np.einsum("ki,ij,kj->k", u, form.Rc, u)
        out.append(J[k0:K].mean())
    return np.array(out)


def _prediction_agrees_with_seeds(sc, loop, net, form):
    """The exact expected cost over the window [T/2, T) agrees with 16 simulated seeds
    within 4 standard errors; returns (Z0, k0, K, prediction)."""
    Z0 = net.initial_state(distributed_initial_state(sc, loop))
    k0, K = sc.steps // 2, sc.steps
    pred = predict_window(net, Z0, k0, K)
    sim = _mc_cost(sc, net, form, Z0, k0, K, range(16))
    se = sim.std(ddof=1) / np.sqrt(sim.size)
    assert abs(sim.mean() - pred.cost_rate) < 4 * se, (sim.mean(), se, pred.cost_rate)
    assert 0.0 < pred.spectral_radius < 1.0
    return Z0, k0, K, pred


@pytest.mark.slow
@pytest.mark.parametrize("receiver, tdma", [("propagate", False), ("hold", False),
                                            ("propagate", True)])
def test_predicted_cost_matches_simulation_over_seeds(f4, receiver, tdma):
    """formation-4 distributed over links of period 2 s, latency 1 s, loss 20 % (and with
    TDMA: the leader and vehicles 1..3 send in turn, four arrival steps per cycle): the
    exact expected cost over the window agrees with 16 simulated seeds within 4 standard
    errors."""
    from plant_model.acoustic.settings import resolve_links
    sc = f4.with_run(T=100.0)
    loop = distributed_loop_of(sc, "kalman", "regulator", sc.distributed)
    form = distributed_message_form(loop, *_H_offsets(sc))
    timings = resolve_links(4, sc.fleet.edges, sc.fleet.pinning,
                            {"latency": 1.0, "period": 2.0, "loss": 0.2, "tdma": tdma}, sc.h)
    net = NetworkedLoop(form, timings, receiver)
    if tdma:
        assert sum(bool(net.pattern(k)[1]) for k in range(200, 240)) == 4
    _prediction_agrees_with_seeds(sc, loop, net, form)


def test_the_second_moment_plan_equals_step_by_step_application(f4):
    """Doubling runs of deterministic steps is exact: the compiled message cycle equals the
    per-step second-moment recursion."""
    loop = distributed_loop_of(f4, "ideal", "regulator", f4.distributed)
    form = distributed_message_form(loop, *_H_offsets(f4))
    net = NetworkedLoop(form, {k: check_link(str(k), 0.5, 1.0, 0.25) for k in form.links},
                        "propagate")
    comp = _Compiler(net)
    b = comp.first_cycle()
    X0 = np.outer(*(2 * [net.initial_state(distributed_initial_state(f4, loop))]))
    fast, cost_fast = comp.apply(comp.cycle(), X0)
    slow, cost_slow = X0, 0.0
    for k in range(b, b + net.period):
        slow, c = comp.apply([comp.step(net.pattern(k))], slow)
        cost_slow += c
    assert np.allclose(fast, slow, rtol=1e-9, atol=1e-9 * np.abs(slow).max())
    assert cost_fast == pytest.approx(cost_slow, rel=1e-9)


def test_no_critical_loss_up_to_0_9_for_the_distributed_law_on_a_survey(f4):
    """Lawnmower leader (marginal exosystem): mean-square stable at 0 and at every loss
    0.1 .. 0.9; with every message lost each vehicle runs on propagated data, second-moment
    radius 1."""
    loop = distributed_loop_of(f4, "kalman", "regulator", f4.distributed)
    form = distributed_message_form(loop, *_H_offsets(f4))
    net = NetworkedLoop(form, {k: check_link(str(k), 1.0, 2.0, 0.2) for k in form.links},
                        "propagate")
    assert frozen_radius(net) == pytest.approx(1.0, abs=1e-9)
    p, note = critical_loss(net)
    assert p is None and note.startswith("none up to 0.9: mean-square stable")
    assert "second-moment radius is 1 per cycle" in note


def _both_sides(form, X0, pc, cycles, seeds=200):
    """The second moment of the error coordinates (no leader, no noise) after ``cycles``
    message cycles at loss pc - 0.1 and pc + 0.1: predicted and simulated, relative to the
    start."""
    out = []
    for p in (pc - 0.1, pc + 0.1):
        net = NetworkedLoop(form, {k: check_link(str(k), 1.0, 2.0, p) for k in form.links},
                            "propagate")
        Z0 = net.initial_state(X0)
        Z0[net.deterministic] = 0.0                  # the error coordinates: no leader
        comp = _Compiler(net)
        b = comp.first_cycle()
        X, _ = comp.apply(comp.plan(0, b), np.outer(Z0, Z0), noise=False)
        for _ in range(cycles):
            X, _ = comp.apply(comp.cycle(), X, noise=False)
        zeta = np.zeros((b + cycles * net.period + 1, form.Gam.shape[1]))
        sims = np.array([np.sum(net.simulate(Z0, zeta, seed)[-1] ** 2)
                         for seed in range(seeds)])
        out.append((np.trace(X) / (Z0 @ Z0), sims.mean() / (Z0 @ Z0)))
    return out


@pytest.mark.slow
def test_a_critical_loss_below_one_checked_by_simulation_on_both_sides():
    """The spiral leader (growth 0.05 1/s, tests/data/spiral-leader-network.toml): a
    propagated message drifts like exp(0.05 t), so the critical loss is near exp(-0.2);
    the second moment of the error coordinates decays below it and grows above it, in the
    prediction and in 200 simulated loss sequences."""
    sc = load_scenario(DATA / "spiral-leader-network.toml")
    loop = distributed_loop_of(sc, "kalman", "regulator", sc.distributed)
    form = distributed_message_form(loop, *_H_offsets(sc))

    def net_at(p):
        return NetworkedLoop(form, {k: check_link(str(k), 1.0, 2.0, p) for k in form.links},
                             "propagate")

    # the second-moment radius: the square of the state transition's exp(0.05 x 2 s)
    assert frozen_radius(net_at(0.2)) == pytest.approx(np.exp(0.2), rel=1e-6)
    pc, _ = critical_loss(net_at(0.2))
    assert pc is not None and abs(pc - np.exp(-0.2)) < 0.03
    assert ms_stable(net_at(pc - 0.05)) is True and ms_stable(net_at(pc + 0.05)) is False
    assert ms_spectral_radius(net_at(pc - 0.05)) < 1.0 < ms_spectral_radius(net_at(pc + 0.08))
    (pred_lo, sim_lo), (pred_hi, sim_hi) = _both_sides(
        form, form.state_of(distributed_initial_state(sc, loop)), pc, 20)
    assert pred_lo < 0.5 and sim_lo < 0.5 and pred_hi > 2.0 and sim_hi > 2.0
    assert sim_lo == pytest.approx(pred_lo, rel=0.35)
    assert sim_hi == pytest.approx(pred_hi, rel=0.35)


@pytest.mark.slow
def test_the_centralized_law_has_a_critical_loss_where_the_distributed_has_none(f4):
    """formation-4 with propagating receivers: the centralized law (every vehicle's estimate,
    propagated with its model and its held control, feeds every other vehicle's control)
    stops being mean-square stable near loss 0.71, although with every message lost the
    loop is marginal: the errors of propagated estimates circulate through the other
    vehicles' controls. The distributed law (only the leader's estimate travels) has none
    up to 0.9. Checked by simulation 0.1 on both sides."""
    loop, form = _centralized(f4, "kalman")
    net = NetworkedLoop(form, {k: check_link(str(k), 1.0, 2.0, 0.2) for k in form.links},
                        "propagate")
    assert frozen_radius(net) == pytest.approx(1.0, abs=1e-9)
    pc, note = critical_loss(net, tol=0.02)
    assert pc is not None and 0.65 < pc < 0.75, note
    (pred_lo, sim_lo), (pred_hi, sim_hi) = _both_sides(
        form, form.state_of(distributed_initial_state(f4, loop)), pc, 30, seeds=100)
    assert pred_lo < 0.1 and sim_lo < 0.1 and pred_hi > 2.0 and sim_hi > 2.0


@pytest.mark.parametrize("architecture, receiver", [
    ("centralized", "propagate"), ("centralized", "hold"), ("distributed", "propagate")])
def test_the_second_moment_in_blocks_equals_the_dense_one(f4, architecture, receiver):
    """networked_blocks keeps the held values apart (block-diagonal between arrivals): the
    same expected window cost as the dense propagation."""
    from orchestrator.analysis.acoustic.blocks import predict_window_blocks
    from orchestrator.running.network import network_setup
    from orchestrator.running.setup import Method
    sc = f4.with_run(T=60.0, deployment="per-vehicle", architecture=architecture,
                     network={"latency": 1.0, "period": 2.0, "loss": 0.2,
                              "receiver": receiver})
    s = network_setup(sc, Method("kalman", "kalman", "regulator", architecture))
    dense = predict_window(s.net, s.Z0, 400, 1200).cost_rate
    blocks = predict_window_blocks(s.net, s.Z0, 400, 1200, 0.0).cost_rate
    assert blocks == pytest.approx(dense, rel=1e-10)
