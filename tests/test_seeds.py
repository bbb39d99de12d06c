"""compare's seeds on local worker processes: the same summary as in one process."""
from __future__ import annotations

import os

import pytest

from orchestrator.running import seeds, simulate


@pytest.mark.slow
def test_seeds_on_worker_processes_give_the_serial_summary(paper, tmp_path, monkeypatch):
    sc = paper.with_run(T=2.0)
    monkeypatch.setattr(seeds, "MIN_PARALLEL_STEPS", 0)
    submitted = []
    real = seeds.SeedPool.submit

    def submit(self, *args):
        fut = real(self, *args)
        submitted.append(fut)
        return fut

    monkeypatch.setattr(seeds.SeedPool, "submit", submit)
    two = simulate(sc, ["kalman", "ideal"], [0, 1, 2], tmp_path / "two", progress=False,
                   log=lambda s: None, workers=2)
    one = simulate(sc, ["kalman", "ideal"], [0, 1, 2], tmp_path / "one", progress=False,
                   log=lambda s: None, workers=1)
    assert len(submitted) == 4                                 # seeds 1, 2 of both methods
    for m in ("kalman", "ideal"):
        assert two["methods"][m]["cost_rate"]["per_seed"] == \
            one["methods"][m]["cost_rate"]["per_seed"]
        assert two["methods"][m]["rms_e"] == one["methods"][m]["rms_e"]
    assert os.path.exists(tmp_path / "two" / "paper.rrd")


def test_not_worth_it_runs_serially():
    with seeds.seed_pool(steps=100, seeds=3, methods=3, workers=2) as pool:
        assert pool is None
    with seeds.seed_pool(steps=10**6, seeds=1, methods=3, workers=2) as pool:
        assert pool is None
    with seeds.seed_pool(steps=10**6, seeds=5, methods=1, workers=1) as pool:
        assert pool is None


@pytest.mark.slow
def test_per_vehicle_seeds_on_worker_processes_give_the_serial_summary(tmp_path, monkeypatch):
    """The per-vehicle deployment over acoustic links goes through the same seed workers
    (the system of each seed made here, run there) and gives the serial figures."""
    from orchestrator.scenario import load_scenario
    sc = load_scenario("formation-4").with_run(
        T=4.0, deployment="per-vehicle", architecture="distributed",
        network={"latency": 0.5, "period": 1.0, "loss": 0.2})
    monkeypatch.setattr(seeds, "MIN_PARALLEL_STEPS", 0)
    two = simulate(sc, None, [0, 1], tmp_path / "two", progress=False, log=lambda s: None,
                   workers=2)
    one = simulate(sc, None, [0, 1], tmp_path / "one", progress=False, log=lambda s: None,
                   workers=1)
    (m,) = two["methods"]
    assert two["methods"][m]["cost_rate"]["per_seed"] == one["methods"][m]["cost_rate"]["per_seed"]
    assert two["methods"][m]["cost_rate"]["per_seed"][0] != \
        two["methods"][m]["cost_rate"]["per_seed"][1]
    assert two["methods"][m]["formation_error_rms"] == one["methods"][m]["formation_error_rms"]
