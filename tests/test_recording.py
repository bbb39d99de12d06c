"""Round-trip tests of orchestrator.recording: what write_rrd logs is exactly what the .rrd holds."""
from __future__ import annotations

import time
import warnings

import numpy as np
import pytest
from rerun.chunk import RrdReader

from orchestrator.recording import (
    TRACE_KEYS,
    method_color,
    read_rrd_blueprint_views,
    read_rrd_scalars,
    read_rrd_series_styles,
    rrd_has_blueprint,
    write_rrd,
)

H = 0.01
H_NS = 10_000_000
STEPS = 317
DIMS = {"x": 3, "w": 1, "z": 2, "e": 2, "u": 2, "xhat": 3, "what": 1, "zhat": 2, "y": 2, "ybar": 1}
METHODS = ("kalman", "classical")

# trace key -> entity path template, as documented in the brief
LAYOUT = {
    "e": "error/{i}/{m}",
    "x": "state/{i}/{m}/true",
    "xhat": "state/{i}/{m}/estimate",
    "u": "control/{i}/{m}",
    "w": "disturbance/{i}/{m}/true",
    "what": "disturbance/{i}/{m}/estimate",
    "z": "reference/{i}/{m}/true",
    "zhat": "reference/{i}/{m}/estimate",
    "y": "measurement/y/{i}/{m}",
    "ybar": "measurement/ybar/{i}/{m}",
}


def make_runs(methods=METHODS, steps=STEPS, dims=DIMS, seed=1234):
    rng = np.random.default_rng(seed)
    return {
        m: {k: rng.standard_normal((steps, d)) * 10.0 ** rng.integers(-6, 6) for k, d in dims.items()}
        for m in methods
    }


def expected_series(runs):
    out = {}
    for m, traces in runs.items():
        for key, template in LAYOUT.items():
            for i in range(1, traces[key].shape[1] + 1):
                out[template.format(i=i, m=m)] = traces[key][:, i - 1]
    return out


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    runs = make_runs()
    path = tmp_path_factory.mktemp("rrd") / "two_methods.rrd"
    info = write_rrd(path, runs, H, recording_name="synthetic round trip")
    return path, runs, info


def test_every_series_round_trips_exactly(written):
    path, runs, info = written
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
    assert set(info) == {"rrd_s", "signals", "bytes"}
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
        assert styles[f"state/3/{m}/true"] == (m, base)
        est_name, est_rgba = styles[f"state/3/{m}/estimate"]
        assert est_name == f"{m} estimate"
        assert est_rgba != base
        # lighter: every channel at least as bright, and brighter overall
        assert all(e >= b for e, b in zip(est_rgba[:3], base[:3])) and sum(est_rgba[:3]) > sum(base[:3])


def test_unknown_methods_get_distinct_colours():
    colors = method_color(["kalman", "classical", "ideal", "foo", "bar"])
    assert len(set(colors.values())) == 5


def test_default_blueprint_is_embedded(written):
    path, _, _ = written
    assert rrd_has_blueprint(path)
    views = read_rrd_blueprint_views(path)
    expected = {}
    for group, dim in (("error", 2), ("state", 3), ("control", 2), ("disturbance", 1), ("reference", 2)):
        for i in range(1, dim + 1):
            expected[f"{group}-{i}"] = ("TimeSeries", f"/{group}/{i}")
    assert views == expected

    # the views sit in one Grid container (ContainerKind.Grid == 4)
    reader = RrdReader(path)
    (bp,) = reader.blueprints()
    grids = []
    for chunk in reader.stream(store=bp):
        batch = chunk.to_record_batch()
        if "ContainerBlueprint:container_kind" in batch.schema.names:
            kind = batch.column("ContainerBlueprint:container_kind").to_pylist()[-1][0]
            contents = batch.column("ContainerBlueprint:contents").to_pylist()[-1]
            grids.append((kind, len(contents)))
    assert grids == [(4, len(expected))]


def test_without_blueprint_helper_says_so(tmp_path):
    import rerun as rr

    path = tmp_path / "plain.rrd"
    rec = rr.RecordingStream("plain")
    rec.save(path)
    rec.send_columns("a", indexes=[rr.TimeColumn("step", sequence=np.arange(3))],
                     columns=rr.Scalars.columns(scalars=np.ones(3)))
    rec.disconnect()
    assert not rrd_has_blueprint(path)


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


def test_different_step_counts_raise(tmp_path):
    runs = make_runs()
    runs["classical"]["u"] = runs["classical"]["u"][:-1]
    with pytest.raises(ValueError, match=r"'classical'.*'u'.*316 steps"):
        write_rrd(tmp_path / "bad.rrd", runs, H, recording_name="bad")

    runs = make_runs()
    runs["classical"] = make_runs(methods=("classical",), steps=STEPS + 5)["classical"]
    with pytest.raises(ValueError, match=r"'classical'.*'x'.*322 steps"):
        write_rrd(tmp_path / "bad2.rrd", runs, H, recording_name="bad")


def test_missing_key_raises(tmp_path):
    runs = make_runs()
    del runs["kalman"]["zhat"]
    with pytest.raises(ValueError, match=r"'kalman'.*missing.*'zhat'"):
        write_rrd(tmp_path / "bad.rrd", runs, H, recording_name="bad")
    assert not (tmp_path / "bad.rrd").exists()


@pytest.mark.parametrize("mutate, pattern", [
    (lambda r: r["kalman"].__setitem__("e", r["kalman"]["e"][:, 0]), r"'kalman'.*'e'.*shape"),
    (lambda r: r.__setitem__("a/b", r.pop("kalman")), r"'a/b'"),
])
def test_malformed_runs_raise(tmp_path, mutate, pattern):
    runs = make_runs()
    mutate(runs)
    with pytest.raises(ValueError, match=pattern):
        write_rrd(tmp_path / "bad.rrd", runs, H, recording_name="bad")


@pytest.mark.parametrize("h", [0.0, -0.01, float("nan"), 1e-12])
def test_bad_step_raises(tmp_path, h):
    with pytest.raises(ValueError, match="step h"):
        write_rrd(tmp_path / "bad.rrd", make_runs(steps=5), h, recording_name="bad")


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
