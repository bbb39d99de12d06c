"""Round-trip tests of orchestrator.recording: what write_rrd logs is exactly what the .rrd holds."""
from __future__ import annotations

import time
import warnings

import numpy as np
import pytest
from rerun.chunk import RrdReader

from orchestrator.recording import (
    TRACE_KEYS,
    FleetLayout,
    method_color,
    read_rrd_line_strips,
    read_rrd_points,
    read_rrd_scalars,
    read_rrd_series,
    read_rrd_series_lines,
    write_rrd,
)
from support.rrd_readback import (
    read_rrd_blueprint_tree,
    read_rrd_blueprint_views,
    read_rrd_series_styles,
    read_rrd_visible_time_ranges,
    rrd_has_blueprint,
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
    with pytest.raises(ValueError, match=r"'classical'.*'e'.*322 steps"):
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


# ---------------------------------------------------------------------------------------------
# Fleet of N vehicles: 3D scene, per-vehicle series, fleet blueprint
# ---------------------------------------------------------------------------------------------

N_VEH = 3
FLEET_STEPS = 263          # not a multiple of the trail stride: the last step closes the trail
FLEET_H = 0.1
FLEET_H_NS = 100_000_000
TRAIL_S = 5.0              # 50 steps
TRAIL_SAMPLE_S = 0.5       # 5 steps
FLEET_METHODS = ("kalman", "classical")
FLEET_DIMS = {"x": 6 * N_VEH, "w": 3 * N_VEH, "z": 2, "e": 3 * N_VEH, "u": 3 * N_VEH,
              "xhat": 6 * N_VEH, "what": 3 * N_VEH, "zhat": 2, "y": 4, "ybar": 2}
EDGES = ((1, 2), (2, 3), (3, 1), (1, 3))
PINNED = (1, 3)
STATE_NAMES = ("north", "east", "down", "u", "v", "r")
CURRENT_NAMES = ("n", "e", "d")


def make_fleet(n=N_VEH, edges=EDGES, pinned=PINNED, **changes):
    """Vehicle i owns the 6-block of x (positions first), 3 errors, 3 controls, and the current
    components i-1, i-1+n, i-1+2n of w (interleaved, to exercise the index arrays)."""
    fields = {
        "position_index": np.arange(6 * n).reshape(n, 6)[:, :3],
        "error_index": np.arange(3 * n).reshape(n, 3),
        "control_index": np.arange(3 * n).reshape(n, 3),
        "error_names": ("north", "east", "down"),
        "control_names": ("X_n", "X_e", "X_d"),
        "leader_output": np.array([[1.0, 0.0], [0.0, 1.0], [0.25, -0.5]]),
        "offsets": np.array([[10.0 * i, -5.0 * i, 1.0 + i] for i in range(n)]),
        "edges": edges,
        "pinned": pinned,
        "state_index": np.arange(6 * n).reshape(n, 6),
        "state_names": STATE_NAMES,
        "disturbance_index": np.arange(3 * n).reshape(3, n).T,
        "disturbance_names": CURRENT_NAMES,
    }
    fields.update(changes)
    return FleetLayout(**fields)


def make_fleet_runs(methods=FLEET_METHODS, steps=FLEET_STEPS, n=N_VEH, seed=99):
    """Vehicles drifting around a moving leader (metres, non-round values), random other traces."""
    rng = np.random.default_rng(seed)
    t = np.arange(steps)[:, None] * FLEET_H
    dims = dict(FLEET_DIMS, x=6 * n, w=3 * n, xhat=6 * n, what=3 * n)
    runs = {}
    for m in methods:
        traces = {k: rng.standard_normal((steps, d)) for k, d in dims.items() if k not in ("x", "e", "u")}
        traces["e"] = rng.standard_normal((steps, 3 * n))
        traces["u"] = rng.standard_normal((steps, 3 * n)) * 100.0
        traces["z"] = np.hstack([3.0 * t + 0.1, 500.0 + 0.5 * np.sin(t)])
        x = rng.standard_normal((steps, 6 * n))
        x[:, 0::6] += 3.0 * t + rng.uniform(-50, 50, n)   # north
        x[:, 1::6] += 500.0 + rng.uniform(-50, 50, n)    # east
        x[:, 2::6] += 20.0 + rng.uniform(0, 5, n)        # down
        traces["x"] = x
        runs[m] = traces
    return runs


def recorded_steps(stride, steps=FLEET_STEPS):
    return np.arange(0, steps, stride)


def sampled_steps(every, stride, steps=FLEET_STEPS):
    """Steps of a decimated 3D entity: multiples of ``every``, then the last recorded step."""
    last = (steps - 1) // stride * stride
    ks = np.arange(0, steps, every)
    return ks if ks[-1] == last else np.append(ks, last)


def trail_stride(stride):
    return stride * max(1, round(TRAIL_SAMPLE_S / (stride * FLEET_H)))


@pytest.fixture(scope="module", params=[1, 3], ids=["stride1", "stride3"])
def fleet_written(request, tmp_path_factory):
    stride = request.param
    runs = make_fleet_runs()
    fleet = make_fleet()
    path = tmp_path_factory.mktemp("rrd") / f"fleet_stride{stride}.rrd"
    info = write_rrd(path, runs, FLEET_H, recording_name="fleet round trip", fleet=fleet,
                     trail_seconds=TRAIL_S, trail_sample_seconds=TRAIL_SAMPLE_S, stride=stride)
    return path, runs, fleet, info, stride


def positions(run, fleet):
    return run["x"][:, fleet.position_index]  # (steps, N, 3) float64


def leader_position(run, fleet):
    return run["z"] @ fleet.leader_output.T  # (steps, 3)


def expected_fleet_series(runs, fleet, stride):
    """Entity -> (rows, k) values of the fleet layout at the recorded steps."""
    ks = recorded_steps(stride)
    out = {}
    for m, run in runs.items():
        for i in range(1, fleet.n_vehicles + 1):
            out[f"vehicles/{i}/error/{m}"] = run["e"][ks][:, fleet.error_index[i - 1]]
            out[f"vehicles/{i}/control/{m}"] = run["u"][ks][:, fleet.control_index[i - 1]]
            out[f"vehicles/{i}/state/{m}/true"] = run["x"][ks][:, fleet.state_index[i - 1]]
            out[f"vehicles/{i}/state/{m}/estimate"] = run["xhat"][ks][:, fleet.state_index[i - 1]]
            out[f"vehicles/{i}/current/{m}/true"] = run["w"][ks][:, fleet.disturbance_index[i - 1]]
            out[f"vehicles/{i}/current/{m}/estimate"] = run["what"][ks][:, fleet.disturbance_index[i - 1]]
        out[f"leader/{m}"] = leader_position(run, fleet)[ks]
    return out


def test_fleet_per_vehicle_series_round_trip(fleet_written):
    path, runs, fleet, info, stride = fleet_written
    ks = recorded_steps(stride)
    expected = expected_fleet_series(runs, fleet, stride)
    for entity, values in expected.items():
        step, sim_time, read = read_rrd_series(path, entity)
        assert step.dtype == np.int64 and sim_time.dtype == np.int64 and read.dtype == np.float64
        assert np.array_equal(step, ks) and np.array_equal(sim_time, ks * FLEET_H_NS), entity
        assert read.shape == values.shape == (ks.size, values.shape[1]), entity
        assert np.array_equal(read, values), entity
    # spot checks against the definitions, column by column
    s = ks.size - 1
    k = ks[s]
    step, _, read = read_rrd_series(path, "/vehicles/2/error/kalman")
    assert np.array_equal(read[:, 1], runs["kalman"]["e"][ks, 4])
    step, _, read = read_rrd_series(path, "vehicles/3/control/classical")
    assert np.array_equal(read[:, 2], runs["classical"]["u"][ks, 8])
    _, _, read = read_rrd_series(path, "vehicles/2/state/kalman/estimate")
    assert np.array_equal(read[s], runs["kalman"]["xhat"][k, 6:12])
    _, _, read = read_rrd_series(path, "vehicles/2/current/classical/true")
    assert np.array_equal(read[s], runs["classical"]["w"][k, [1, 4, 7]])
    # read_rrd_scalars sees the same (rows, k) arrays, and nothing else: no per-component layout
    got = read_rrd_scalars(path)
    assert set(got) == set(expected)
    for entity, values in expected.items():
        assert np.array_equal(got[entity][0], ks) and np.array_equal(got[entity][2], values), entity
    assert info["signals"] == sum(v.shape[1] for v in expected.values()) == len(FLEET_METHODS) * (
        N_VEH * (3 + 3 + 6 + 6 + 3 + 3) + 3)
    assert set(info) == {"rrd_s", "signals", "bytes"} and info["bytes"] == path.stat().st_size


def test_fleet_has_no_per_component_layout(fleet_written):
    path, _, _, _, _ = fleet_written
    entities = set(read_rrd_scalars(path))
    assert not any(e.startswith(tuple(f"{root}/" for root in (
        "error", "state", "control", "disturbance", "reference", "measurement"))) for e in entities)
    assert set(read_rrd_series_lines(path)) == entities
    with pytest.raises(KeyError):
        read_rrd_series(path, "error/1/kalman")


def test_fleet_series_lines(fleet_written):
    path, _, fleet, _, _ = fleet_written
    lines = read_rrd_series_lines(path)
    colors = method_color(list(FLEET_METHODS))
    for m in FLEET_METHODS:
        base = colors[m] + (255,)
        for i in (1, N_VEH):
            names, rgba = lines[f"vehicles/{i}/error/{m}"]
            assert names == tuple(f"{m} {c}" for c in fleet.error_names)
            assert rgba[0] == base and len(set(rgba)) == len(rgba) == 3  # distinct shades
            names, rgba = lines[f"vehicles/{i}/control/{m}"]
            assert names == tuple(f"{m} {c}" for c in fleet.control_names) and rgba[0] == base
            true_names, true_rgba = lines[f"vehicles/{i}/state/{m}/true"]
            est_names, est_rgba = lines[f"vehicles/{i}/state/{m}/estimate"]
            assert true_names == tuple(f"{m} {c}" for c in STATE_NAMES)
            assert est_names == tuple(f"{m} {c} estimate" for c in STATE_NAMES)
            assert len(set(true_rgba)) == 6
            for t, e in zip(true_rgba, est_rgba):  # estimates: lighter shade of the same colour
                assert all(b >= a for a, b in zip(t[:3], e[:3])) and sum(e[:3]) > sum(t[:3])
            assert lines[f"vehicles/{i}/current/{m}/true"][0] == tuple(f"{m} {c}" for c in CURRENT_NAMES)
            assert lines[f"vehicles/{i}/current/{m}/estimate"][0] == tuple(
                f"{m} {c} estimate" for c in CURRENT_NAMES)
        assert lines[f"leader/{m}"][0] == (f"{m} leader north", f"{m} leader east", f"{m} leader down")
    # the first-line view of the same styles
    styles = read_rrd_series_styles(path)
    assert styles["vehicles/1/error/kalman"] == ("kalman north", colors["kalman"] + (255,))


def test_fleet_vehicle_positions_round_trip(fleet_written):
    path, runs, fleet, _, stride = fleet_written
    ks = recorded_steps(stride)
    for m in FLEET_METHODS:
        step, sim_time, pts = read_rrd_points(path, f"world/{m}/vehicles")
        assert np.array_equal(step, ks) and np.array_equal(sim_time, ks * FLEET_H_NS)
        assert pts.dtype == np.float32 and pts.shape == (ks.size, N_VEH, 3)
        want = positions(runs[m], fleet)[ks].astype(np.float32)  # Rerun positions are float32
        assert np.array_equal(pts, want)
        for s in (0, 1, 77, ks.size - 1):
            for i in range(N_VEH):
                assert np.array_equal(pts[s, i],
                                      runs[m]["x"][ks[s], [6 * i, 6 * i + 1, 6 * i + 2]].astype(np.float32))
    # the two methods are kept apart
    a = read_rrd_points(path, "/world/kalman/vehicles")[2]
    b = read_rrd_points(path, "world/classical/vehicles")[2]
    assert not np.array_equal(a, b)


def test_fleet_leader_and_targets(fleet_written):
    path, runs, fleet, _, stride = fleet_written
    ks = recorded_steps(stride)
    for m in FLEET_METHODS:
        lead = leader_position(runs[m], fleet)[ks]
        step, _, got_lead = read_rrd_points(path, f"world/{m}/leader")
        assert np.array_equal(step, ks)
        assert got_lead.shape == (ks.size, 1, 3)
        assert np.array_equal(got_lead[:, 0], lead.astype(np.float32))
        _, _, got_targets = read_rrd_points(path, f"world/{m}/targets")
        want = (lead[:, None, :] + fleet.offsets[None, :, :]).astype(np.float32)
        assert np.array_equal(got_targets, want)
        for s in (0, 50, ks.size - 1):
            for i in range(N_VEH):
                np.testing.assert_allclose(got_targets[s, i], lead[s] + fleet.offsets[i], rtol=1e-6)


def check_edges(path, runs, fleet, es):
    for m in FLEET_METHODS:
        step, sim_time, strips = read_rrd_line_strips(path, f"world/{m}/edges")
        veh = positions(runs[m], fleet)[es].astype(np.float32)
        lead = leader_position(runs[m], fleet)[es].astype(np.float32)
        assert np.array_equal(step, es) and np.array_equal(sim_time, es * FLEET_H_NS)
        assert strips.shape == (es.size, len(fleet.edges) + len(fleet.pinned), 2, 3)
        for e, (j, i) in enumerate(fleet.edges):  # from vehicle j to vehicle i
            assert np.array_equal(strips[:, e, 0], veh[:, j - 1]), (j, i)
            assert np.array_equal(strips[:, e, 1], veh[:, i - 1]), (j, i)
        for p, i in enumerate(fleet.pinned):      # from the leader to the pinned vehicle
            assert np.array_equal(strips[:, len(fleet.edges) + p, 0], lead)
            assert np.array_equal(strips[:, len(fleet.edges) + p, 1], veh[:, i - 1])


def test_fleet_edges_join_the_vehicles_at_the_trail_rate(fleet_written):
    path, runs, fleet, _, stride = fleet_written
    es = sampled_steps(trail_stride(stride), stride)   # default scene_stride: the trail stride
    assert set(es) <= set(recorded_steps(stride))      # edges sit on recorded vehicle samples
    check_edges(path, runs, fleet, es)


@pytest.mark.parametrize("stride, scene_stride", [(1, 1), (1, 7), (2, 8)])
def test_fleet_scene_stride(tmp_path, stride, scene_stride):
    runs = make_fleet_runs()
    fleet = make_fleet()
    path = tmp_path / "scene.rrd"
    write_rrd(path, runs, FLEET_H, recording_name="scene", fleet=fleet, stride=stride, scene_stride=scene_stride)
    check_edges(path, runs, fleet, sampled_steps(scene_stride, stride))
    step, _, _ = read_rrd_points(path, "world/kalman/vehicles")
    assert np.array_equal(step, recorded_steps(stride))


def test_fleet_trails_are_decimated_segments(fleet_written):
    path, runs, fleet, _, stride = fleet_written
    ks = sampled_steps(trail_stride(stride), stride)
    if stride == 1:  # the historical case: every 5 steps, then the last step 262
        assert np.array_equal(ks, np.append(np.arange(0, FLEET_STEPS, 5), FLEET_STEPS - 1))
    for m in FLEET_METHODS:
        step, sim_time, strips = read_rrd_line_strips(path, f"world/{m}/trails")
        assert np.array_equal(step, ks[1:]) and np.array_equal(sim_time, ks[1:] * FLEET_H_NS)
        assert strips.shape == (ks.size - 1, N_VEH, 2, 3)
        pos = positions(runs[m], fleet).astype(np.float32)
        assert np.array_equal(strips[:, :, 0], pos[ks[:-1]])
        assert np.array_equal(strips[:, :, 1], pos[ks[1:]])
        assert np.array_equal(strips[1:, :, 0], strips[:-1, :, 1])  # one connected trail per vehicle


def test_fleet_default_state_and_no_current(tmp_path):
    """Without state_index the state entities hold the positions; without disturbance_index no current."""
    runs = make_fleet_runs(methods=("ideal",), steps=40)
    fleet = make_fleet(state_index=None, state_names=None, disturbance_index=None, disturbance_names=None)
    path = tmp_path / "defaults.rrd"
    info = write_rrd(path, runs, FLEET_H, recording_name="defaults", fleet=fleet, stride=4)
    ks = recorded_steps(4, steps=40)
    step, _, read = read_rrd_series(path, "vehicles/3/state/ideal/true")
    assert np.array_equal(step, ks) and np.array_equal(read, runs["ideal"]["x"][ks][:, [12, 13, 14]])
    _, _, read = read_rrd_series(path, "vehicles/3/state/ideal/estimate")
    assert np.array_equal(read, runs["ideal"]["xhat"][ks][:, [12, 13, 14]])
    lines = read_rrd_series_lines(path)
    assert lines["vehicles/1/state/ideal/true"][0] == ("ideal north", "ideal east", "ideal down")
    assert not any("/current/" in e for e in lines)
    assert info["signals"] == N_VEH * (3 + 3 + 3 + 3) + 3


def _static_component(path, entity, column):
    for chunk in RrdReader(path).stream():
        if chunk.is_static and chunk.entity_path.strip("/") == entity:
            batch = chunk.to_record_batch()
            if column in batch.schema.names:
                return batch.column(column).to_pylist()[-1]
    return None


def test_fleet_world_is_ned_and_labelled(fleet_written):
    path, _, _, _, _ = fleet_written
    frd = [5, 3, 2]  # ViewDir Forward, Right, Down: x north, y east, z down
    assert _static_component(path, "world", "ViewCoordinates:xyz") == [frd]
    for m in FLEET_METHODS:
        assert _static_component(path, f"world/{m}", "ViewCoordinates:xyz") == [frd]
        assert _static_component(path, f"world/{m}/vehicles", "Points3D:labels") == ["1", "2", "3"]
        assert _static_component(path, f"world/{m}/vehicles", "Points3D:radii") == [1.0]
        assert _static_component(path, f"world/{m}/leader", "Points3D:labels") == ["leader"]


def _views(node):
    if node["kind"] == "view":
        return [node]
    return [v for child in node["contents"] for v in _views(child)]


def test_fleet_blueprint_layout(fleet_written):
    path, _, _, _, _ = fleet_written
    tree = read_rrd_blueprint_tree(path)
    assert tree["kind"] == "Horizontal" and len(tree["contents"]) == 2
    left, right = tree["contents"]
    # left: one 3D view per method in tabs, the first method first
    assert left["kind"] == "Tabs"
    assert [(v["class"], v["name"], v["origin"]) for v in left["contents"]] == [
        ("3D", f"fleet {m}", f"/world/{m}") for m in FLEET_METHODS]
    # right: per-vehicle error and control views in a 2-column grid (N <= 8); their origins are
    # the parents of the per-method entities, so each view overlays every method
    assert right["kind"] == "Grid"
    assert [(v["class"], v["name"], v["origin"]) for v in right["contents"]] == [
        ("TimeSeries", f"vehicle {i} {g}", f"/vehicles/{i}/{g}")
        for i in range(1, N_VEH + 1) for g in ("error", "control")]
    entities = set(read_rrd_scalars(path))
    for i in range(1, N_VEH + 1):
        for g in ("error", "control"):
            assert {e for e in entities if e.startswith(f"vehicles/{i}/{g}/")} == {
                f"vehicles/{i}/{g}/{m}" for m in FLEET_METHODS}
    # read_rrd_blueprint_views lists them too, and the per-component grid is left out
    views = read_rrd_blueprint_views(path)
    assert views["fleet kalman"] == ("3D", "/world/kalman")
    assert views["vehicle 2 control"] == ("TimeSeries", "/vehicles/2/control")
    assert set(views) == {v["name"] for v in _views(tree)}
    assert "error-1" not in views and len(views) == len(FLEET_METHODS) + 2 * N_VEH


def test_fleet_trail_visible_time_range(fleet_written):
    path, _, _, _, _ = fleet_written
    ranges = read_rrd_visible_time_ranges(path)
    want = {
        "sim_time": (("cursor_relative", -round(TRAIL_S * 1e9)), ("cursor_relative", 0)),
        "step": (("cursor_relative", -round(TRAIL_S / FLEET_H)), ("cursor_relative", 0)),
    }
    # only the trail entities carry a range; the rest of the 3D view shows the latest sample
    assert ranges == {(f"fleet {m}", f"/world/{m}/trails"): want for m in FLEET_METHODS}


def test_fleet_many_vehicles_use_tabs(tmp_path):
    n = 10
    runs = make_fleet_runs(methods=("ideal",), steps=12, n=n, seed=5)
    fleet = make_fleet(n=n, edges=tuple((i, i + 1) for i in range(1, n)), pinned=(1,))
    path = tmp_path / "ten.rrd"
    write_rrd(path, runs, FLEET_H, recording_name="ten", fleet=fleet)
    tree = read_rrd_blueprint_tree(path)
    left, right = tree["contents"]
    assert (left["kind"], left["class"], left["origin"]) == ("view", "3D", "/world/ideal")
    assert right["kind"] == "Tabs"
    assert [t["name"] for t in right["contents"]] == ["vehicles 1-4", "vehicles 5-8", "vehicles 9-10"]
    assert all(t["kind"] == "Grid" for t in right["contents"])
    assert [v["origin"] for v in _views(right)] == [
        f"/vehicles/{i}/{g}" for i in range(1, n + 1) for g in ("error", "control")]
    # default trail: 60 s on both timelines
    assert read_rrd_visible_time_ranges(path)[("fleet ideal", "/world/ideal/trails")] == {
        "sim_time": (("cursor_relative", -60_000_000_000), ("cursor_relative", 0)),
        "step": (("cursor_relative", -600), ("cursor_relative", 0)),
    }
    step, _, edges = read_rrd_line_strips(path, "world/ideal/edges")
    assert np.array_equal(step, [0, 5, 10, 11]) and edges.shape == (4, n, 2, 3)
    _, _, read = read_rrd_series(path, "vehicles/10/current/ideal/estimate")
    assert np.array_equal(read, runs["ideal"]["what"][:, [9, 19, 29]])


def test_no_fleet_file_has_no_fleet_entities(written):
    path, _, _ = written
    assert read_rrd_visible_time_ranges(path) == {}
    tree = read_rrd_blueprint_tree(path)
    assert tree["kind"] == "Grid" and all(v["class"] == "TimeSeries" for v in _views(tree))
    with pytest.raises(KeyError):
        read_rrd_points(path, "world/kalman/vehicles")
    assert not any(e.startswith(("vehicles/", "leader/")) for e in read_rrd_scalars(path))


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


@pytest.mark.parametrize("stride", [0, -1, 1.5, 2.0, True, "2", None])
@pytest.mark.parametrize("with_fleet", [False, True])
def test_bad_stride_raises(tmp_path, stride, with_fleet):
    kwargs = {"fleet": make_fleet()} if with_fleet else {}
    runs = make_fleet_runs(methods=("kalman",), steps=10)
    with pytest.raises(ValueError, match="stride must be a positive integer"):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", stride=stride, **kwargs)
    assert not (tmp_path / "bad.rrd").exists()


@pytest.mark.parametrize("stride, scene_stride, pattern", [
    (1, 0, "scene_stride must be a positive integer"),
    (1, 2.5, "scene_stride must be a positive integer"),
    (3, 4, r"scene_stride = 4 must be a multiple of stride = 3"),
])
def test_bad_scene_stride_raises(tmp_path, stride, scene_stride, pattern):
    runs = make_fleet_runs(methods=("kalman",), steps=10)
    with pytest.raises(ValueError, match=pattern):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet(),
                  stride=stride, scene_stride=scene_stride)


def test_numpy_integer_stride_is_accepted(tmp_path):
    runs = make_fleet_runs(methods=("kalman",), steps=10)
    write_rrd(tmp_path / "ok.rrd", runs, FLEET_H, recording_name="ok", fleet=make_fleet(), stride=np.int64(3))
    assert np.array_equal(read_rrd_series(tmp_path / "ok.rrd", "leader/kalman")[0], [0, 3, 6, 9])


@pytest.mark.parametrize("changes, pattern", [
    ({"position_index": np.array([[0, 1, 2], [6, 7, 8], [12, 13, 18]])},
     r"position_index\[2, 2\] = 18 .*out of range.*'x'.*18 columns"),
    ({"position_index": np.array([[0, 1], [6, 7], [12, 13]])}, r"position_index must have shape \(N, 3\)"),
    ({"position_index": np.array([[0.0, 1, 2], [6, 7, 8], [12, 13, 14]])}, r"position_index must be an integer"),
    ({"error_index": np.array([[0, 1, 2], [3, 4, 5], [6, 7, 9]])}, r"error_index\[2, 2\] = 9 .*'e'"),
    ({"error_index": np.arange(6).reshape(2, 3)}, r"error_index has 2 rows"),
    ({"control_index": np.array([[-1, 1, 2], [3, 4, 5], [6, 7, 8]])}, r"control_index\[0, 0\] = -1 .*'u'"),
    ({"error_names": ("north", "east")}, r"error_names has 2 labels"),
    ({"control_names": ("X_n", "X/e", "X_d")}, r"control_names label 'X/e'"),
    ({"offsets": np.zeros((3, 2))}, r"offsets must have shape \(N, 3\) = \(3, 3\), got shape \(3, 2\)"),
    ({"offsets": np.zeros((2, 3))}, r"offsets must have shape"),
    ({"leader_output": np.eye(3)}, r"leader_output must have shape \(3, l\) = \(3, 2\)"),
    ({"edges": ((1, 2), (2, 4))}, r"edges\[1\] = \(2, 4\) names vehicle 4.*N = 3"),
    ({"edges": ((0, 1),)}, r"edges\[0\] = \(0, 1\) names vehicle 0"),
    ({"edges": ((1, 2, 3),)}, r"edges\[0\].*not a pair"),
    ({"edges": ((2, 2),)}, r"edges\[0\] = \(2, 2\) is a self-loop"),
    ({"pinned": (1, 7)}, r"pinned\[1\] names vehicle 7"),
    ({"state_index": np.arange(18).reshape(3, 6) + 1}, r"state_index\[2, 5\] = 18 .*'x'"),
    ({"state_index": np.arange(12).reshape(2, 6)}, r"state_index has 2 rows"),
    ({"state_index": np.arange(18.0).reshape(3, 6)}, r"state_index must be an integer"),
    ({"state_names": STATE_NAMES[:5]}, r"state_names has 5 labels.*state_index has 6"),
    ({"state_names": None}, r"state_names must be a tuple of strings"),
    ({"state_index": None}, r"state_names has 6 labels.*position_index has 3"),
    ({"disturbance_index": np.arange(9).reshape(3, 3) + 1}, r"disturbance_index\[2, 2\] = 9 .*'w'"),
    ({"disturbance_names": ("n", "n", "d")}, r"disturbance_names labels must be distinct"),
    ({"disturbance_index": None}, r"disturbance_names is given without fleet.disturbance_index"),
])
def test_bad_fleet_layout_raises(tmp_path, changes, pattern):
    runs = make_fleet_runs(methods=("kalman",), steps=10)
    with pytest.raises(ValueError, match=pattern):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet(**changes))
    assert not (tmp_path / "bad.rrd").exists()


def test_fleet_checked_against_every_run(tmp_path):
    runs = make_fleet_runs(methods=("kalman", "classical"), steps=10)
    runs["classical"]["u"] = runs["classical"]["u"][:, :8]
    with pytest.raises(ValueError, match=r"control_index\[2, 2\] = 8 .*'classical' trace 'u'"):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet())
    runs = make_fleet_runs(methods=("kalman", "classical"), steps=10)
    runs["kalman"]["xhat"] = runs["kalman"]["xhat"][:, :17]
    with pytest.raises(ValueError, match=r"state_index\[2, 5\] = 17 .*'kalman' trace 'xhat'"):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet())
    runs = make_fleet_runs(methods=("kalman", "classical"), steps=10)
    runs["classical"]["what"] = runs["classical"]["what"][:, :8]
    with pytest.raises(ValueError, match=r"disturbance_index\[2, 2\] = 8 .*'classical' trace 'what'"):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet())


@pytest.mark.parametrize("kwargs", [{"trail_seconds": 0.0}, {"trail_seconds": float("nan")},
                                    {"trail_sample_seconds": -1.0}])
def test_bad_trail_settings_raise(tmp_path, kwargs):
    runs = make_fleet_runs(methods=("kalman",), steps=10)
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        write_rrd(tmp_path / "bad.rrd", runs, FLEET_H, recording_name="bad", fleet=make_fleet(), **kwargs)
