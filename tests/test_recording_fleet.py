"""The per-vehicle series write_rrd records for a fleet of N vehicles (instead of the
per-component layout): error, control, state, current and leader of each vehicle and method,
read back at the recorded steps, with their series names and colours, and the defaults of a
FleetLayout without state or current indices."""
from __future__ import annotations

import numpy as np
import pytest

from orchestrator.recording import (
    read_rrd_scalars,
    read_rrd_series,
    read_rrd_series_lines,
    write_rrd,
)
from orchestrator.recording.layout import axis_colors, fleet_method_line
from support.recording import (
    CURRENT_NAMES,
    FLEET_H,
    FLEET_H_NS,
    FLEET_METHODS,
    N_VEH,
    STATE_NAMES,
    leader_position,
    make_fleet,
    make_fleet_runs,
    recorded_steps,
)
from support.rrd_readback import read_rrd_series_styles


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
    assert set(info) == {"rrd_s", "signals", "bytes", "recorded_groups"}
    assert info["bytes"] == path.stat().st_size
    assert info["recorded_groups"] == ["error", "control", "state", "current", "leader", "scene"]


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
    every = set()
    for j, m in enumerate(FLEET_METHODS):
        # one hue per component (north red, east green, down blue), one shade per method;
        # the first of several methods see-through (and wide: fleet_method_line)
        alpha = fleet_method_line(j, len(FLEET_METHODS))[1]
        axes = tuple(c + (alpha,) for c in axis_colors(3, j))
        for i in (1, N_VEH):
            names, rgba = lines[f"vehicles/{i}/error/{m}"]
            assert names == tuple(f"{m} {c}" for c in fleet.error_names)
            assert rgba == axes and len(set(rgba)) == 3
            every.update(rgba)
            names, rgba = lines[f"vehicles/{i}/control/{m}"]
            assert names == tuple(f"{m} {c}" for c in fleet.control_names) and rgba == axes
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
    assert len(every) == 3 * len(FLEET_METHODS)          # the methods' lines differ too
    assert axis_colors(3, 0) == [(214, 39, 40), (44, 160, 44), (31, 119, 180)]
    # the first-line view of the same styles
    styles = read_rrd_series_styles(path)
    first = fleet_method_line(0, len(FLEET_METHODS))[1]
    assert styles["vehicles/1/error/kalman"] == ("kalman north", (214, 39, 40, first))


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
