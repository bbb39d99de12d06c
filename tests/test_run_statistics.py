"""The statistics accumulated chunk by chunk as a run goes
(orchestrator/running/statistics.py) against those of the whole traces: real per-vehicle
runs on real FMUs (a fleet over acoustic links; a fleet whose controllers clip their
force), run once whole and once to a recorder in uneven chunks. Maxima, counts, fractions
and the closest approach are equal; sums to rounding; the kept traces equal the whole run's
bit for bit."""
from __future__ import annotations

import math

import numpy as np
import pytest

from orchestrator.running.setup import Method, run_statistics, stats_context
from orchestrator.running.statistics import (
    CHUNK_BYTES,
    MAX_CHUNK_STEPS,
    MIN_CHUNK_STEPS,
    RunRecorder,
    RunStatistics,
    chunk_steps,
)
from orchestrator.running.systems import make_setup
from orchestrator.scenario import load_scenario


def _close(a, b, path=""):
    """Equal structure; floats equal to 1e-12 relative (sums), others exactly."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            _close(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _close(x, y, f"{path}[{i}]")
    elif isinstance(a, float):
        assert math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-300), (path, a, b)
    else:
        assert a == b, path


EXACT = ("max_error", "max_error_straight", "max_error_turns", "turn_fraction",
         "actuator_saturation_fraction", "actuator_saturation_fraction_per_vehicle")


def _chunked_against_whole(tmp_path, sc, k0, chunk):
    setup = make_setup(sc, tmp_path / "fmus")
    method = Method.of(sc)
    formation = stats_context(sc)
    whole = setup.run(method, sc.seed)
    ref = run_statistics(sc, whole, k0, formation)
    rec = RunRecorder(RunStatistics(sc, k0, formation), keep=True, chunk=chunk)
    res = setup.run(method, sc.seed, recorder=rec)
    got = rec.statistics.result()
    _close(ref, got)
    for key in EXACT:
        assert ref["segments"].get(key) == got["segments"].get(key), key
    for key in ("min_separation", "min_separation_vehicles", "min_separation_time_s"):
        assert ref["formation"][key] == got["formation"][key], key
    assert res.steps == sc.steps and set(res.traces) == set(whole.traces)
    for key, v in whole.traces.items():
        assert np.array_equal(v.view(np.uint64), res.traces[key].view(np.uint64)), key
    return whole, res, rec


@pytest.mark.slow
def test_chunked_statistics_over_links_equal_the_whole_runs(tmp_path):
    sc = load_scenario("formation-4-links").with_run(T=30.0, fmus="native")
    whole, res, rec = _chunked_against_whole(tmp_path, sc, k0=1234, chunk=577)
    # the age of information per link: the window's mean and max of the whole trace
    ages = rec.statistics.link_ages(res.info["links"])
    assert list(ages) == whole.info["links"] and len(ages) >= 4
    for c, name in enumerate(whole.info["links"]):
        col = whole.traces["link_age"][1234:, c]
        total, count, largest = ages[name]
        assert count == col.size and largest == col.max()
        assert math.isclose(total / count, col.mean(), rel_tol=1e-12)
    assert col.max() > 1.0                 # a 1 s latency and 2 s period: ages over 1 s


@pytest.mark.slow
def test_chunked_saturation_and_turns_equal_the_whole_runs(tmp_path):
    sc = load_scenario("survey-4-remus").with_run(T=40.0, fmus="native")
    _, _, rec = _chunked_against_whole(tmp_path, sc, k0=700, chunk=333)
    seg = rec.statistics.result()["segments"]
    assert seg["actuator_saturation_fraction"] is not None


def test_the_chunk_length_is_a_power_of_two_within_the_budget():
    for width in (1, 7, 20, 3001, 10 ** 6):
        n = chunk_steps(width)
        assert MIN_CHUNK_STEPS <= n <= MAX_CHUNK_STEPS and n & (n - 1) == 0
        assert n in (MIN_CHUNK_STEPS, MAX_CHUNK_STEPS) or \
            n * 8 * width <= CHUNK_BYTES < 2 * n * 8 * width
