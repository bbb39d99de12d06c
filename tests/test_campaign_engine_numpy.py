"""The numpy engine: the closed loop vectorised over seeds gives the FMU co-simulation's
statistics to 1e-9 (same seed, same noise rows), for every estimator and a fleet."""
from __future__ import annotations

import numpy as np
import pytest

from orchestrator.analysis.summary import trace_stats
from orchestrator.campaign.engine_numpy import numpy_unsupported, run_batch
from orchestrator.campaign.tasks import point_design
from plant_model.discretization import discretize
from plant_model.plant import NoiseStream
from support.loop import run_cosimulation


def test_next_rows_is_the_row_by_row_stream(paper):
    model = discretize(paper.system, paper.h)
    st = NoiseStream(model, 7, block=100)
    rows = np.vstack([st.next_rows(30), st.next_rows(170), st.next_rows(1)])
    assert np.array_equal(rows, NoiseStream.all_rows(model, 7, 201))
    one = NoiseStream(model, 7, block=64)
    assert np.array_equal(np.array([one.next_row().copy() for _ in range(201)]), rows)


def _close(a, b):
    assert a["cost_rate"] == pytest.approx(b["cost_rate"], rel=1e-9)
    for k in ("rms_e", "rms_u", "mean_e"):
        assert np.allclose(a[k], b[k], rtol=1e-9, atol=1e-12), k


@pytest.mark.parametrize("mode", ["kalman", "classical", "ideal"])
def test_equal_to_the_fmus(paper, built_scenario, mode):
    fmus, cfg = built_scenario("paper")
    sc = paper.with_run(T=3.0, estimator=mode)
    d = point_design(sc)
    seeds = [0, 5, 11]
    got = run_batch(d.model, d.est, d.Ks, sc.system.initial_state(), sc.system.Q, sc.system.R,
                    seeds, sc.steps, d.k0)
    for seed, stats in zip(seeds, got):
        res = run_cosimulation(fmus, dict(cfg, T=sc.T), mode=mode, seed=seed, steps=sc.steps)
        _close(stats, trace_stats(res.traces, sc.system.Q, sc.system.R, d.k0))
    assert got[0]["cost_rate"] != got[1]["cost_rate"]            # seeds differ


def test_equal_to_the_fmus_for_a_fleet(formation4, built_scenario):
    fmus, cfg = built_scenario("formation-4")
    sc = formation4.with_run(T=2.0)
    d = point_design(sc)
    [stats] = run_batch(d.model, d.est, d.Ks, sc.system.initial_state(), sc.system.Q,
                        sc.system.R, [3], sc.steps, d.k0)
    res = run_cosimulation(fmus, dict(cfg, T=sc.T), mode=sc.estimator, seed=3, steps=sc.steps,
                           tracking=sc.tracking)
    _close(stats, trace_stats(res.traces, sc.system.Q, sc.system.R, d.k0))


def test_a_batch_is_reproducible_and_sub_batches_agree(paper, monkeypatch):
    """The same batch gives the same bits; another batching agrees to rounding only (BLAS
    multiplies a different number of rows: numpy_batches fixes each batch's seeds)."""
    from orchestrator.campaign import engine_numpy
    sc = paper.with_run(T=2.0)
    d = point_design(sc)
    args = (d.model, d.est, d.Ks, sc.system.initial_state(), sc.system.Q, sc.system.R,
            [1, 2, 3], sc.steps, d.k0)
    whole = run_batch(*args)
    assert run_batch(*args) == whole
    monkeypatch.setattr(engine_numpy, "TRACE_BYTES", 1)             # one seed at a time
    for a, b in zip(run_batch(*args), whole):
        _close(a, b)


def test_what_it_does_not_run():
    assert numpy_unsupported("gauss-seidel", {"simulation", "vehicles"}) is None
    assert "Gauss-Seidel" in numpy_unsupported("jacobi", {"simulation"})
    assert "network" in numpy_unsupported("gauss-seidel", {"simulation", "network"})
