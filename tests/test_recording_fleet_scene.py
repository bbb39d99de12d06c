"""The 3D scene write_rrd records for a fleet, read back: vehicle, leader and target points,
the formation edges and the decimated trails (at the trail rate or scene_stride), and the NED
world with its labels."""
from __future__ import annotations

import numpy as np
import pytest
from rerun.chunk import RrdReader

from orchestrator.recording import read_rrd_line_strips, read_rrd_points, write_rrd
from support.recording import (
    FLEET_H,
    FLEET_H_NS,
    FLEET_METHODS,
    FLEET_STEPS,
    N_VEH,
    TRAIL_SAMPLE_S,
    leader_position,
    make_fleet,
    make_fleet_runs,
    recorded_steps,
)


def sampled_steps(every, stride, steps=FLEET_STEPS):
    """Steps of a decimated 3D entity: multiples of ``every``, then the last recorded step."""
    last = (steps - 1) // stride * stride
    ks = np.arange(0, steps, every)
    return ks if ks[-1] == last else np.append(ks, last)


def trail_stride(stride):
    return stride * max(1, round(TRAIL_SAMPLE_S / (stride * FLEET_H)))


def positions(run, fleet):
    return run["x"][:, fleet.position_index]  # (steps, N, 3) float64


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
        # the leader is unlabelled (a label covered vehicles) and its whole path is drawn
        assert _static_component(path, f"world/{m}/leader", "Points3D:labels") is None
        assert _static_component(path, f"world/{m}/leader_path", "LineStrips3D:strips") \
            is not None
