"""Round-trip tests of write_rrd in the per-component ("paper") layout: what it logs is exactly
what the .rrd holds (every series, both timelines, decimation by stride), the figures it returns,
a finished file with its recording name, and the series names and colours of each method."""
from __future__ import annotations

import time
import warnings

import numpy as np
from rerun.chunk import RrdReader

from orchestrator.recording import (
    TRACE_KEYS,
    method_color,
    read_rrd_scalars,
    read_rrd_series,
    write_rrd,
)
from orchestrator.recording.layout import TRUE_COLOR
from support.recording import (
    DIMS,
    H_NS,
    LAYOUT,
    METHODS,
    STEPS,
    H,
    expected_series,
    make_runs,
)
from support.rrd_readback import read_rrd_series_styles


def test_every_series_round_trips_exactly(written):
    path, runs, _info = written
    expected = expected_series(runs)
    got = read_rrd_scalars(path)

    assert set(got) == set(expected)
    assert len(expected) == 2 * sum(DIMS.values())
    k = np.arange(STEPS, dtype=np.int64)
    for entity, values in expected.items():
        step, sim_time, read = got[entity]
        assert step.dtype == np.int64 and sim_time.dtype == np.int64 and read.dtype == np.float64
        assert np.array_equal(step, k), entity
        assert np.array_equal(sim_time, k * H_NS), entity
        assert np.array_equal(read, values), entity


def test_returned_figures(written):
    path, runs, info = written
    assert set(info) == {"rrd_s", "signals", "bytes", "recorded_groups"}
    assert info["recorded_groups"] == ["error", "state", "control", "disturbance", "reference",
                                      "measurement"]
    assert info["signals"] == len(expected_series(runs))
    assert info["bytes"] == path.stat().st_size > 0
    assert info["rrd_s"] > 0.0


def test_file_is_finished_with_footer(written):
    path, _, _ = written
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a file without footer makes RrdReader warn
        reader = RrdReader(path)
        store = reader.store()  # raises for a file without footer/manifest
    assert len(store) > 0
    assert [r.application_id for r in reader.recordings()] == ["auv-cosim"]


def test_recording_name_is_stored(written):
    path, _, _ = written
    names = []
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        if "RecordingInfo:name" in batch.schema.names:
            names += [v[0] for v in batch.column("RecordingInfo:name").to_pylist() if v]
    assert names == ["synthetic round trip"]


def test_series_names_and_colours(written):
    path, runs, _ = written
    styles = read_rrd_series_styles(path)
    assert set(styles) == set(expected_series(runs))
    colors = method_color(list(METHODS))
    assert colors["kalman"] != colors["classical"]
    for m in METHODS:
        base = colors[m] + (255,)
        name, rgba = styles[f"error/1/{m}"]
        assert (name, rgba) == (m, base)
        # the state depends on the method's control: its colour; the reference is shared
        assert styles[f"state/3/{m}/true"] == (m, base)
        assert styles[f"reference/1/{m}/true"] == ("true", TRUE_COLOR + (255,))
        est_name, est_rgba = styles[f"state/3/{m}/estimate"]
        assert est_name == f"{m} estimate"
        assert est_rgba != base
        # lighter: every channel at least as bright, and brighter overall
        assert all(e >= b for e, b in zip(est_rgba[:3], base[:3])) and sum(est_rgba[:3]) > sum(base[:3])


def test_unknown_methods_get_distinct_colours():
    colors = method_color(["kalman", "classical", "ideal", "foo", "bar"])
    assert len(set(colors.values())) == 5


def test_one_method_and_repeated_calls(tmp_path):
    # a dedicated stream per call: two files in one process do not mix
    runs_a = make_runs(methods=("ideal",), steps=50, seed=1)
    runs_b = make_runs(methods=("some_other",), steps=80, seed=2)
    write_rrd(tmp_path / "a.rrd", runs_a, 0.05, recording_name="a")
    write_rrd(tmp_path / "b.rrd", runs_b, 0.001, recording_name="b")
    got_a, got_b = read_rrd_scalars(tmp_path / "a.rrd"), read_rrd_scalars(tmp_path / "b.rrd")
    exp_a, exp_b = expected_series(runs_a), expected_series(runs_b)
    assert set(got_a) == set(exp_a) and set(got_b) == set(exp_b)
    for entity, values in exp_a.items():
        assert np.array_equal(got_a[entity][2], values)
        assert np.array_equal(got_a[entity][1], np.arange(50) * 50_000_000)
    for entity, values in exp_b.items():
        assert np.array_equal(got_b[entity][2], values)
        assert np.array_equal(got_b[entity][1], np.arange(80) * 1_000_000)


def test_trace_keys_match_layout():
    assert set(TRACE_KEYS) == set(LAYOUT) == set(DIMS)


def test_timing_three_methods_30000_steps(tmp_path):
    """Measure (print, not assert) the write time of 3 methods x 30,000 steps, 2-dim traces."""
    steps = 30_000
    runs = make_runs(methods=("kalman", "classical", "ideal"), steps=steps,
                     dims={k: 2 for k in TRACE_KEYS}, seed=7)
    t0 = time.perf_counter()
    info = write_rrd(tmp_path / "timing.rrd", runs, H, recording_name="timing")
    total = time.perf_counter() - t0
    print(f"\nwrite_rrd 3 methods x {steps} steps, 2-dim: {info['signals']} signals, "
          f"rrd_s={info['rrd_s']:.3f} s (call {total:.3f} s), {info['bytes'] / 1e6:.1f} MB")
    assert info["signals"] == 3 * 2 * len(TRACE_KEYS)
    got = read_rrd_scalars(tmp_path / "timing.rrd")
    assert np.array_equal(got["control/2/ideal"][2], runs["ideal"]["u"][:, 1])
    assert np.array_equal(got["control/2/ideal"][1], np.arange(steps) * H_NS)


def test_paper_layout_with_stride(tmp_path):
    """stride also decimates the per-component layout; times stay the true ones."""
    runs = make_runs(steps=101)
    path = tmp_path / "strided.rrd"
    info = write_rrd(path, runs, H, recording_name="strided", stride=7)
    ks = np.arange(0, 101, 7)
    got = read_rrd_scalars(path)
    expected = expected_series(runs)
    assert set(got) == set(expected) and info["signals"] == len(expected)
    for entity, values in expected.items():
        step, sim_time, read = got[entity]
        assert np.array_equal(step, ks) and np.array_equal(sim_time, ks * H_NS), entity
        assert np.array_equal(read, values[ks]), entity
    step, _, read = read_rrd_series(path, "state/3/kalman/estimate")
    assert read.shape == (ks.size, 1) and np.array_equal(read[:, 0], runs["kalman"]["xhat"][ks, 2])
