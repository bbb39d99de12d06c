"""The blueprint write_rrd embeds in a .rrd, read back: the grid of per-component views of the
paper layout, and the fleet layout (3D view per method, per-vehicle error/control views in a grid
or in tabs of grids) with the visible time range of the trails."""
from __future__ import annotations

import numpy as np
import pytest
from rerun.chunk import RrdReader

from orchestrator.recording import (
    read_rrd_line_strips,
    read_rrd_points,
    read_rrd_scalars,
    read_rrd_series,
    write_rrd,
)
from support.recording import (
    FLEET_H,
    FLEET_METHODS,
    FLEET_STRIDE_IDS,
    FLEET_STRIDES,
    N_VEH,
    TRAIL_S,
    make_fleet,
    make_fleet_runs,
    write_fleet_recording,
    write_paper_recording,
)
from support.rrd_readback import (
    read_rrd_blueprint_tree,
    read_rrd_blueprint_views,
    read_rrd_visible_time_ranges,
    rrd_has_blueprint,
)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    return write_paper_recording(tmp_path_factory)


@pytest.fixture(scope="module", params=FLEET_STRIDES, ids=FLEET_STRIDE_IDS)
def fleet_written(request, tmp_path_factory):
    return write_fleet_recording(tmp_path_factory, request.param)


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
