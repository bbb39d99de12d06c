"""Where a run's time goes (orchestrator.running.phases) and the faster window sums.

The phase clock counts each phase's own time (nested phases and measured parts apart);
the window sums of the predictions (the mean motion of the distributed loop, the leader's
second moment of the full-information bound) are done in blocks of samples now: the block
size changes nothing but rounding.
"""
from __future__ import annotations

import time

import numpy as np
import pytest

from orchestrator.running import phases


def test_nested_phases_count_their_own_time():
    """A phase inside another, and a part added inside it, are counted once each."""
    phases.reset()
    t0 = time.perf_counter()
    with phases.phase("build"):
        time.sleep(0.05)
        with phases.phase("design"):
            time.sleep(0.1)
        with phases.phase("instantiate"):
            time.sleep(0.03)
            phases.add("loop", 0.02)            # measured inside: not instantiate's
    split = phases.split(time.perf_counter() - t0)
    assert set(split) == set(phases.PHASES)
    assert 0.09 <= split["design"] < 0.2
    assert 0.04 <= split["build"] < 0.09          # without the design's 0.1 s
    assert split["loop"] == 0.02
    assert 0.005 <= split["instantiate"] < 0.05   # its 0.03 s less the loop's 0.02 s
    assert abs(sum(split.values()) - (time.perf_counter() - t0)) < 0.01
    assert split["other"] >= -1e-6
    phases.reset()
    assert phases.split(1.0) == {**{p: 0.0 for p in phases.PHASES}, "other": 1.0}


def test_zbar_in_one_product_equals_the_sum_of_outer_products():
    """The leader's mean z z' over a window, as one product of the samples, is the sum of
    the per-sample outer products; a second call with equal content is a copy from the cache."""
    from orchestrator.analysis.full_information import _zbar
    rng = np.random.default_rng(3)
    Phi = np.linalg.qr(rng.standard_normal((4, 4)))[0] * 0.999
    z0 = rng.standard_normal(4)
    k0, K = 17, 900
    z = np.linalg.matrix_power(Phi, k0) @ z0
    S = np.zeros((4, 4))
    for _ in range(k0, K):
        S += np.outer(z, z)
        z = Phi @ z
    got = _zbar(Phi, z0, k0, K)
    assert np.allclose(got, S / (K - k0), rtol=1e-12, atol=1e-15)
    again = _zbar(Phi.copy(), z0.copy(), k0, K)
    assert np.array_equal(again, got) and again is not got
    again[0, 0] = 1e9                                 # the cached value is not shared
    assert _zbar(Phi, z0, k0, K)[0, 0] == got[0, 0]


@pytest.mark.parametrize("block", [1, 7])
def test_the_window_mean_motion_does_not_depend_on_the_block(block, monkeypatch):
    """predict_cost over a window with the mean motion: blocks of 1 sample (the former
    per-sample sums) or 7 give the default block's cost and RMS to 1e-12."""
    from orchestrator.analysis import distributed_verdict as dv
    from orchestrator.analysis.per_vehicle import distributed_initial_state, distributed_loop_of
    from orchestrator.scenario import load_scenario
    sc = load_scenario("formation-4").with_run(T=5.0, deployment="per-vehicle",
                                               architecture="distributed")
    loop = distributed_loop_of(sc, "kalman", sc.tracking, sc.distributed)
    X0 = distributed_initial_state(sc, loop)
    ref = dv.predict_cost(loop, (40, sc.steps), X0)
    monkeypatch.setattr(dv, "_MEAN_BLOCK", block)
    got = dv.predict_cost(loop, (40, sc.steps), X0)
    assert got.cost_rate == pytest.approx(ref.cost_rate, rel=1e-12)
    assert np.allclose(got.rms_e, ref.rms_e, rtol=1e-12)
    assert np.allclose(got.rms_u, ref.rms_u, rtol=1e-12)
    mean_only = ref.cost_rate - dv.predict_cost(loop).cost_rate
    assert mean_only > 1e-6 * ref.cost_rate           # the mean motion is in it


@pytest.mark.slow
def test_bench_phases_splits_a_whole_run(capsys):
    """``bench --phases`` runs ``auv-cosim run`` as a subprocess: every phase is counted,
    the run's phases sum to its summary's wall time, the subprocess took longer than that
    (start-up), and the printed lines name every phase with its share."""
    import json

    from orchestrator.cli.entry import main
    assert main(["bench", "--phases", "--scenario", "formation-4", "--deployment",
                 "per-vehicle", "--architecture", "distributed", "--T", "5", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["argv"] == ["--scenario", "formation-4", "--deployment", "per-vehicle",
                         "--architecture", "distributed", "--T", "5.0"]
    ph = r["phases_s"]
    assert set(ph) == set(phases.PHASES)
    for key in ("build", "design", "predictions", "instantiate", "loop", "recording"):
        assert ph[key] > 0, key
    assert sum(ph.values()) == pytest.approx(r["wall_s"], abs=0.05)
    assert r["command_s"] > r["wall_s"] and r["startup_and_exit_s"] > 0.1
    assert r["outside_loop_s"] == pytest.approx(r["command_s"] - ph["loop"])
    assert main(["bench", "--phases", "--scenario", "paper", "--T", "2"]) == 0
    printed = capsys.readouterr().out
    for word in ("build", "design", "predictions", "instantiate", "loop", "statistics",
                 "recording", "other", "start-up", "outside the loop"):
        assert word in printed, word


def test_a_distributed_prediction_is_read_back_bit_for_bit(tmp_path, monkeypatch):
    """predict_cost of a fleet: the second call (a fresh loop object of the same content,
    as a second run makes) is read from the cache folder and equals the first bit for bit;
    another window is another entry; with the cache off nothing is written."""
    from orchestrator.analysis import distributed_verdict as dv
    from orchestrator.analysis.per_vehicle import distributed_initial_state, distributed_loop_of
    from orchestrator.scenario import load_scenario
    monkeypatch.setenv("AUV_COSIM_PREDICTION_CACHE", str(tmp_path / "cache"))
    sc = load_scenario("formation-4").with_run(T=5.0, deployment="per-vehicle",
                                               architecture="distributed")
    loop = distributed_loop_of(sc, "kalman", sc.tracking, sc.distributed)
    X0 = distributed_initial_state(sc, loop)
    first = dv.predict_cost(loop, (40, sc.steps), X0)
    files = list((tmp_path / "cache").glob("distributed-cost-*.json"))
    assert len(files) == 1
    calls = []
    monkeypatch.setattr(dv, "_predict_cost", lambda *a: calls.append(a))
    again = dv.predict_cost(distributed_loop_of(sc, "kalman", sc.tracking, sc.distributed),
                            (40, sc.steps), X0)
    assert not calls and again == first
    monkeypatch.undo()
    monkeypatch.setenv("AUV_COSIM_PREDICTION_CACHE", str(tmp_path / "cache"))
    other = dv.predict_cost(loop, (41, sc.steps), X0)
    assert other.cost_rate != first.cost_rate
    assert len(list((tmp_path / "cache").glob("distributed-cost-*.json"))) == 2
    monkeypatch.setenv("AUV_COSIM_PREDICTION_CACHE", "0")
    assert dv.predict_cost(loop, (42, sc.steps), X0).cost_rate > 0
    assert len(list((tmp_path / "cache").glob("distributed-cost-*.json"))) == 2


def test_closest_approach_equals_the_all_pairs_definition():
    """formation_stats' closest approach (per coordinate, squared, over blocks of samples)
    is the minimum of ||p_i - p_j|| over every pair and sample, bit for bit, with its pair
    and time, also where a block boundary (256 samples) splits the run."""
    from orchestrator.analysis.formation import formation_stats
    rng = np.random.default_rng(5)
    N, steps = 9, 600
    x = rng.standard_normal((steps, 3 * N)) * 4
    idx = np.arange(3 * N).reshape(N, 3)
    pos = x[:, idx]
    d = np.sqrt(np.sum((pos[:, :, None, :] - pos[:, None, :, :]) ** 2, axis=-1))
    d[:, np.tril(np.ones((N, N), dtype=bool))] = np.inf
    k, i, j = np.unravel_index(np.argmin(d), d.shape)
    r = formation_stats(x, idx, np.zeros((N, 3)), [(1, 2)], 0, 0.1)
    assert r["min_separation"] == d[k, i, j]
    assert r["min_separation_vehicles"] == [i + 1, j + 1]
    assert r["min_separation_time_s"] == pytest.approx(k * 0.1)
