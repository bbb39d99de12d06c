"""The per-process design cache: identical numbers hit, results are read-only and equal to
solving again, FMU instances of one process share it, and it can be turned off."""
from __future__ import annotations

import numpy as np
import pytest

from controller_fmu.regulator import tracking_law
from plant_model.discretization import discretize
from plant_model.memo import cache_stats, clear_caches, content_key
from support.loop import run_cosimulation


def test_content_key():
    a = np.arange(4.0).reshape(2, 2)
    assert content_key(a, "x", 1) == content_key(a.copy(), "x", 1)
    assert content_key(a) != content_key(a.T.copy())                 # bytes
    assert content_key(a) != content_key(a.reshape(4))               # shape
    assert content_key(a) != content_key(a.astype(np.float32))       # dtype
    assert content_key(1) != content_key(1.0) != content_key(True)
    assert content_key({"b": 1, "a": [2]}) == content_key({"a": [2], "b": 1})
    with pytest.raises(TypeError):
        content_key(object())


def test_hits_are_equal_and_read_only(paper, monkeypatch):
    clear_caches()
    law = tracking_law(paper.system, "lq")
    again = tracking_law(paper.system, "lq")
    assert again is law and cache_stats()["tracking_law"] == {"hits": 1, "misses": 1, "size": 1}
    with pytest.raises(ValueError):
        law.Ks[0, 0] = 1.0
    monkeypatch.setenv("AUV_COSIM_DESIGN_CACHE", "0")
    fresh = tracking_law(paper.system, "lq")
    assert fresh is not law and np.array_equal(fresh.Ks, law.Ks)
    changed = paper.system.with_changes(Q=2 * paper.system.Q)
    monkeypatch.delenv("AUV_COSIM_DESIGN_CACHE")
    assert not np.array_equal(tracking_law(changed, "lq").Ks, law.Ks)      # a new key
    assert discretize(paper.system, 0.01) is discretize(paper.system, 0.01)
    assert discretize(paper.system, 0.02) is not discretize(paper.system, 0.01)


def test_fmu_instances_share_the_design(built_scenario, monkeypatch):
    """The second seed's FMUs find the first one's sampled model, Kalman gains and law."""
    fmus, cfg = built_scenario("paper")
    clear_caches()
    a = run_cosimulation(fmus, cfg, mode="kalman", seed=1, steps=50)
    first = cache_stats()
    b = run_cosimulation(fmus, cfg, mode="kalman", seed=1, steps=50)
    second = cache_stats()
    for name in ("discretize", "steady_kalman", "tracking_law"):
        assert first[name]["misses"] >= 1
        assert second[name]["misses"] == first[name]["misses"], name      # no new solve
        assert second[name]["hits"] > first[name]["hits"], name
    monkeypatch.setenv("AUV_COSIM_DESIGN_CACHE", "0")
    c = run_cosimulation(fmus, cfg, mode="kalman", seed=1, steps=50)
    for k in a.traces:                                # the same bits with or without it
        assert np.array_equal(a.traces[k], b.traces[k]) and np.array_equal(a.traces[k],
                                                                           c.traces[k])
