"""orchestrator.analysis.acoustic.stability and .cache: the second-moment radius by Arnoldi
iteration on the matrix-free cycle map against the dense operator, the critical-loss
search against the certificate search it replaced and a dense bisection, the on-disk
cache (a real second run, and a changed input), and ``--predict none``."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import block_diag

from orchestrator.analysis.acoustic.cycle import _Compiler
from orchestrator.analysis.acoustic.loop import NetworkedLoop
from orchestrator.analysis.acoustic.message_form import Link, MessageForm, Sender
from orchestrator.analysis.acoustic.stability import (
    ARPACK_NCV,
    CycleMap,
    critical_loss,
    frozen_radius,
    ms_spectral_radius,
    ms_stable,
)
from plant_model.acoustic.links import check_link

GRID = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)


def _orth(rng: np.random.Generator, k: int) -> np.ndarray:
    q, _ = np.linalg.qr(rng.standard_normal((k, k)))
    return q


def toy_loop(loss: float = 0.3, gain: float = 0.3, seed: int = 7) -> NetworkedLoop:
    """Two vehicles of 6 states (x+ = 0.6 Q x + gain Q' r), each sending 3 of them to the
    other every 0.5 s with 0.3 s latency (h = 0.1 s); the receivers propagate the held
    message with 1.08 Q'' per step, so with every message lost the copies drift: a critical
    loss between 0 and 1. 24 states, small enough for the dense n^2 x n^2 operator."""
    rng = np.random.default_rng(seed)
    s, w = 6, 3
    Phi = block_diag(0.6 * _orth(rng, s), 0.6 * _orth(rng, s))
    Cm = [np.hstack([np.eye(w), np.zeros((w, s))]), np.hstack([np.zeros((w, s)), np.eye(w)])]
    senders = {j: Sender(Cm=Cm[j - 1], Dm=np.zeros((w, 2 * s)), M_prop=1.08 * _orth(rng, w))
               for j in (1, 2)}
    links = {}
    for j, i in ((1, 2), (2, 1)):
        B = np.zeros((2 * s, w))
        B[(i - 1) * s:(i - 1) * s + w] = gain * _orth(rng, w)
        links[(j, i)] = Link(sender=j, receiver=i, B=B, Gu=np.zeros((1, w)))
    form = MessageForm(Phi=Phi, Gam=np.eye(2 * s), W=0.01 * np.eye(2 * s),
                       Gx=np.zeros((1, 2 * s)), Geta=np.zeros((1, 2 * s)), Ce=np.eye(2 * s),
                       Qc=np.eye(2 * s), Rc=np.eye(1), deterministic=np.zeros(2 * s, bool),
                       h=0.1, senders=senders, links=links, architecture="distributed")
    return NetworkedLoop(form, {k: check_link(str(k), 0.3, 0.5, loss) for k in links},
                         "propagate")


def dense_radius(net: NetworkedLoop, loss: float) -> float:
    """rho of the cycle's second-moment operator built densely, step by step from the
    loop's matrices: L_k = Abar (x) Abar + sum_l p (1 - p) D_l (x) D_l, L = L_(P-1) ... L_0
    (no compilation, no doubling, no Krylov)."""
    n, P = net.n, net.period
    b = -(-net.startup // P) * P
    L = np.eye(n * n)
    for k in range(b, b + P):
        A0, D = net.matrices(net.pattern(k))
        Ds = [Dl[:, :n].toarray() for Dl in D.values()]
        Abar = A0[:, :n].toarray() + sum((1.0 - loss) * Dl for Dl in Ds)
        L = (np.kron(Abar, Abar) + sum(loss * (1.0 - loss) * np.kron(Dl, Dl) for Dl in Ds)) @ L
    return float(np.max(np.abs(np.linalg.eigvals(L))))


@pytest.fixture
def no_cache(monkeypatch):
    monkeypatch.setenv("AUV_COSIM_PREDICTION_CACHE", "0")


@pytest.mark.parametrize("loss", [0.0, 0.3, 0.6, 1.0])
def test_the_krylov_radius_equals_the_dense_operator_on_a_two_vehicle_loop(no_cache, loss):
    net = toy_loop()
    n = CycleMap(_Compiler(net, loss=loss, error_only=True)).n
    assert n * (n + 1) // 2 > 4 * ARPACK_NCV            # Arnoldi, not the tiny-loop path
    want = dense_radius(net, loss)
    assert ms_spectral_radius(net, loss) == pytest.approx(want, rel=1e-9)
    if loss == 1.0:       # every message lost: the second-moment radius, rho(G)^2
        assert frozen_radius(net) == pytest.approx(want, rel=1e-9)
        assert want > 1.5


def _old_search(net: NetworkedLoop, tol: float) -> float | None:
    """The search as it was: certificates (ms_stable) at 0, on the grid, then bisection."""
    assert ms_stable(net, 0.0) is True
    lo = 0.0
    for p in GRID:
        v = ms_stable(net, p)
        assert v is not None
        if not v:
            hi = p
            break
        lo = p
    else:
        return None
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        v = ms_stable(net, mid)
        assert v is not None
        lo, hi = (mid, hi) if v else (lo, mid)
    return 0.5 * (lo + hi)


def _dense_search(net: NetworkedLoop, tol: float) -> tuple[float, float, float]:
    """Grid, then bisection, on the dense operator's radius: (p, lo, hi)."""
    lo = 0.0
    hi = next(p for p in GRID if dense_radius(net, p) >= 1.0)
    lo = max([0.0] + [p for p in GRID if p < hi])
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if dense_radius(net, mid) < 1.0 else (lo, mid)
    return 0.5 * (lo + hi), lo, hi


@pytest.mark.slow
def test_the_spiral_leaders_critical_loss_equals_the_certificate_search(no_cache):
    """tests/data/spiral-leader-network.toml: at small losses a mode the links do not touch
    dominates (0.875 per cycle); the loss-driven one overtakes it near 0.7. Arnoldi
    started from the small losses' eigenvector alone stays in that mode's invariant
    subspace and finds no critical loss; started from it plus I, the search finds the
    certificate search's bracket."""
    from orchestrator.analysis.acoustic.message_form import distributed_message_form
    from orchestrator.analysis.per_vehicle import distributed_loop_of
    from orchestrator.scenario import load_scenario
    sc = load_scenario(Path(__file__).parent / "data" / "spiral-leader-network.toml")
    loop = distributed_loop_of(sc, "kalman", "regulator", sc.distributed)
    form = distributed_message_form(loop, sc.fleet.leader.H,
                                    sc.fleet.offsets)
    net = NetworkedLoop(form, {k: check_link(str(k), 1.0, 2.0, 0.2) for k in form.links},
                        "propagate")
    assert ms_spectral_radius(net, 0.1) == pytest.approx(0.875173, abs=1e-6)
    p, note = critical_loss(net)
    assert p == _old_search(net, 0.01) == 0.815625, note
    assert note.startswith("bisection: stable at 0.8125, not at 0.8188")


@pytest.mark.parametrize("tol", [0.01, 0.001])
def test_the_critical_loss_equals_the_certificate_search_and_a_dense_bisection(no_cache, tol):
    net = toy_loop()
    p, note = critical_loss(net, tol=tol)
    want, lo, hi = _dense_search(net, tol)
    assert p == want and 0.2 < p < 0.6, note
    assert note.startswith(f"bisection: stable at {lo:.4g}, not at {hi:.4g}")
    if tol == 0.01:       # finer, the certificates leave the midpoints undecided
        assert _old_search(net, tol) == p
    assert dense_radius(net, lo) < 1.0 <= dense_radius(net, hi)
    assert f"second-moment radius is {dense_radius(net, 1.0):.6g} per cycle" in note


def test_the_cache_returns_the_same_values_and_a_changed_input_computes_again(
        tmp_path, monkeypatch):
    """A second computation on a new loop object (nothing kept in the process) reads the
    file the first wrote, bit for bit, and does not search again (it would say so); a
    loop with another loss probability or another gain is a new entry."""
    monkeypatch.setenv("AUV_COSIM_PREDICTION_CACHE", str(tmp_path))
    said: list[str] = []
    first = critical_loss(toy_loop(), log=said.append)
    rho = ms_spectral_radius(toy_loop())
    assert len(said) == 1 and said[0].startswith("searching the critical loss")
    files = sorted(p.name for p in tmp_path.iterdir())
    assert len(files) == 2 and {f.split("-")[0] for f in files} == {"critical", "ms"}
    again = critical_loss(toy_loop(), log=said.append)
    assert again == first and len(said) == 1                  # from the file, not searched
    assert ms_spectral_radius(toy_loop()) == rho
    # another link loss: the radius and the note's search change (the critical loss is
    # that of a common loss, the same p, but the key differs: computed again)
    other = toy_loop(loss=0.35)
    assert ms_spectral_radius(other) > rho
    critical_loss(other, log=said.append)
    assert len(said) == 2
    # another gain: another critical loss
    changed = critical_loss(toy_loop(gain=0.32), log=said.append)
    assert len(said) == 3 and changed[0] != first[0]
    assert len(list(tmp_path.iterdir())) == 5


def _run(out, *extra, env=None):
    cmd = [sys.executable, "-m", "orchestrator", "run", "--scenario", "formation-4",
           "--deployment", "per-vehicle", "--architecture", "distributed", "--latency", "1",
           "--period", "2", "--T", "10", "--h", "0.05", "--out", str(out), *extra]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600,
                       env=dict(os.environ, **(env or {})))
    assert r.returncode == 0, r.stderr
    return r.stdout, json.loads((out / "summary.json").read_text())


@pytest.mark.slow
def test_predict_none_writes_nulls_and_a_note(tmp_path):
    stdout, summary = _run(tmp_path / "none", "--loss", "0.2", "--predict", "none",
                           env={"AUV_COSIM_PREDICTION_CACHE": "0"})
    m = summary["methods"]["kalman"]
    note = "no prediction: --predict none asked for none"
    assert m["cost_rate"]["predicted"] is None and m["cost_rate"]["predicted_window"] is None
    assert m["rms_e"]["predicted"] is None and m["spectral_radius"] is None
    assert m["prediction_note"] == note
    assert m["network"]["critical_loss"] is None and m["network"]["critical_loss_note"] == note
    assert m["cost_rate"]["mean"] > 0 and summary["stats_window_s"] == [5.0, 10.0]
    assert "predicted" not in stdout.split("cost rate")[1].split("\n")[0]


@pytest.mark.slow
def test_a_second_run_takes_the_predictions_from_the_cache(tmp_path):
    """Three real runs with one cache folder: the second finds every prediction of the
    first (the same figures, no search announced); with another loss, a new search."""
    env = {"AUV_COSIM_PREDICTION_CACHE": str(tmp_path / "cache")}
    said = "searching the critical loss"
    out1, s1 = _run(tmp_path / "a", "--loss", "0.2", "--predict", "full", env=env)
    n1 = len(list((tmp_path / "cache").iterdir()))
    out2, s2 = _run(tmp_path / "b", "--loss", "0.2", "--predict", "full", env=env)
    assert said in out1 and said not in out2
    m1, m2 = s1["methods"]["kalman"], s2["methods"]["kalman"]
    assert m2["cost_rate"]["predicted"] == m1["cost_rate"]["predicted"] is not None
    assert m2["spectral_radius"] == m1["spectral_radius"]
    assert m2["network"]["critical_loss_note"] == m1["network"]["critical_loss_note"]
    assert len(list((tmp_path / "cache").iterdir())) == n1 == 3   # radius, window, search
    out3, s3 = _run(tmp_path / "c", "--loss", "0.3", "--predict", "full", env=env)
    assert said in out3
    assert s3["methods"]["kalman"]["cost_rate"]["predicted"] != m1["cost_rate"]["predicted"]
    assert len(list((tmp_path / "cache").iterdir())) == 6
