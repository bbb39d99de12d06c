"""The blueprint write_rrd embeds in a .rrd, read back: the grid of per-component views of the
paper layout, and the fleet layout (3D view per method, per-vehicle error/control views in a grid
or in tabs of grids) with the visible time range of the trails."""
from __future__ import annotations

import numpy as np
import pytest

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
    N_VEH,
    TRAIL_S,
    make_fleet,
    make_fleet_runs,
)
from support.rrd_readback import (
    read_rrd_blueprint_tree,
    read_rrd_blueprint_views,
    read_rrd_view_properties,
    read_rrd_visible_time_ranges,
    rrd_has_blueprint,
)


def _views(node):
    if node["kind"] == "view":
        return [node]
    return [v for c in node["contents"] for v in _views(c)]


def test_default_blueprint_is_embedded(written):
    """Legend line on top, then tabs: the paper's figures (error, state, control rows),
    disturbance & reference, and the estimates at full scale; every container full (no
    empty cell), every plot over the whole run with its legend hidden."""
    path, runs, _ = written
    assert rrd_has_blueprint(path)
    tree = read_rrd_blueprint_tree(path)
    assert tree["kind"] == "Vertical"
    legend, tabs = tree["contents"]
    assert (legend["class"], legend["origin"]) == ("TextDocument", "/legend")
    assert tabs["kind"] == "Tabs"
    names = [t["name"] for t in tabs["contents"]]
    assert names == ["paper figures 2-7", "disturbance & reference", "estimates, full scale"]
    dims = {"error": 2, "state": 3, "control": 2, "disturbance": 1, "reference": 2}
    figures, exo, full = tabs["contents"]
    assert [(r["kind"], r["name"], len(r["contents"])) for r in figures["contents"]] == [
        ("Horizontal", g, dims[g]) for g in ("error", "state", "control")]
    assert [(r["name"], len(r["contents"])) for r in exo["contents"]] == [
        ("disturbance", 1), ("reference", 2)]
    assert [(r["name"], len(r["contents"])) for r in full["contents"]] == [
        ("state, full scale", 3), ("disturbance, full scale", 1), ("reference, full scale", 2)]
    for row in figures["contents"] + exo["contents"]:
        for i, view in enumerate(row["contents"], start=1):
            assert view["class"] == "TimeSeries" and view["origin"] == f"/{row['name']}/{i}"
            assert view["name"].startswith(f"{row['name']}-{i} (dimensionless)")
    props = read_rrd_view_properties(path)
    ranges = read_rrd_visible_time_ranges(path)
    series = [v["name"] for v in _views(tree) if v["class"] == "TimeSeries"]
    assert len(series) == 10 + 6
    for name in series:
        assert props[name]["PlotLegend:visible"] == [False]
        assert ranges[(name, None)] == {"sim_time": (("infinite", None), ("infinite", None)),
                                        "step": (("infinite", None), ("infinite", None))}


def test_estimate_views_fit_the_true_signal(tmp_path):
    """The state view's y-axis is the true signal's range plus 15 %; an estimate that leaves
    it more than 1 % of the time is only in the full-scale view, and the name says so."""
    from orchestrator.recording.blueprint import true_signal_range
    rng = np.random.default_rng(5)
    steps = 400
    x = np.cumsum(rng.standard_normal((steps, 2)), axis=0)
    runs = {}
    for m, noise in (("kalman", 0.05), ("classical", 30.0)):
        runs[m] = {k: rng.standard_normal((steps, 2)) for k in
                   ("e", "u", "w", "what", "z", "zhat", "y", "ybar")}
        runs[m]["x"] = x
        runs[m]["xhat"] = x + noise * rng.standard_normal((steps, 2))
    path = tmp_path / "fit.rrd"
    write_rrd(path, runs, 0.01, recording_name="fit")
    props = read_rrd_view_properties(path)
    for i in (1, 2):
        name = f"state-{i} (dimensionless) · classical estimate: see full scale"
        lo, hi = props[name]["ScalarAxis:range"][0]
        assert (lo, hi) == pytest.approx(true_signal_range(x[:, i - 1]))
        assert lo < x[:, i - 1].min() and hi > x[:, i - 1].max()
        trues = [f"+ /state/{i}/kalman/true", f"+ /state/{i}/classical/true"]
        assert props[name]["ViewContents:query"] == trues + [f"+ /state/{i}/kalman/estimate"]
        full = f"state-{i} full scale (dimensionless)"
        assert props[full]["ViewContents:query"] == trues + [
            f"+ /state/{i}/kalman/estimate", f"+ /state/{i}/classical/estimate"]
        # the shared reference: drawn once
        ref = props["reference-1 (dimensionless)"]["ViewContents:query"]
        assert ref[0] == "+ /reference/1/kalman/true"
        assert "+ /reference/1/classical/true" not in ref
        # the full-scale view's axis covers every estimate, the classical one too
        lo, hi = props[full]["ScalarAxis:range"][0]
        every = np.concatenate([x[:, i - 1]] + [runs[m]["xhat"][:, i - 1] for m in runs])
        assert lo < every.min() and hi > every.max()


def test_without_blueprint_helper_says_so(tmp_path):
    import rerun as rr

    path = tmp_path / "plain.rrd"
    rec = rr.RecordingStream("plain")
    rec.save(path)
    rec.send_columns("a", indexes=[rr.TimeColumn("step", sequence=np.arange(3))],
                     columns=rr.Scalars.columns(scalars=np.ones(3)))
    rec.disconnect()
    assert not rrd_has_blueprint(path)


def test_fleet_blueprint_layout(fleet_written):
    path, _, _, _, _ = fleet_written
    tree = read_rrd_blueprint_tree(path)
    assert tree["kind"] == "Vertical" and len(tree["contents"]) == 2
    legend, body = tree["contents"]
    assert (legend["class"], legend["origin"]) == ("TextDocument", "/legend")
    assert body["kind"] == "Horizontal" and len(body["contents"]) == 2
    left, right = body["contents"]
    # left: one 3D view per method in tabs, the first method first
    assert left["kind"] == "Tabs"
    assert [(v["class"], v["name"], v["origin"]) for v in left["contents"]] == [
        ("3D", f"fleet {m}", f"/world/{m}") for m in FLEET_METHODS]
    # right: per-vehicle error and control views in a 2-column grid (N <= 8); their origins are
    # the parents of the per-method entities, so each view overlays every method
    assert right["kind"] == "Grid"
    assert [(v["class"], v["name"], v["origin"]) for v in right["contents"]] == [
        ("TimeSeries", f"vehicle {i} {g} ({unit})", f"/vehicles/{i}/{g}")
        for i in range(1, N_VEH + 1) for g, unit in (("error", "m"), ("control", "N"))]
    entities = set(read_rrd_scalars(path))
    for i in range(1, N_VEH + 1):
        for g in ("error", "control"):
            assert {e for e in entities if e.startswith(f"vehicles/{i}/{g}/")} == {
                f"vehicles/{i}/{g}/{m}" for m in FLEET_METHODS}
    # read_rrd_blueprint_views lists them too, and the per-component grid is left out
    views = read_rrd_blueprint_views(path)
    assert views["fleet kalman"] == ("3D", "/world/kalman")
    assert views["vehicle 2 control (N)"] == ("TimeSeries", "/vehicles/2/control")
    assert set(views) == {v["name"] for v in _views(tree)}
    assert "error-1" not in views and len(views) == len(FLEET_METHODS) + 2 * N_VEH + 1
    # every 3D view looks at the centre of everything the run visits, from above and south
    _, runs, fleet_layout, _, _ = fleet_written
    props = read_rrd_view_properties(path)
    pts = np.concatenate([np.concatenate([r["x"][:, np.asarray(fleet_layout.position_index)]
                                          .reshape(-1, 3),
                                          r["z"] @ np.asarray(fleet_layout.leader_output).T])
                          for r in runs.values()])
    centre = (pts.min(axis=0) + pts.max(axis=0)) / 2
    for m in FLEET_METHODS:
        eye = props[f"fleet {m}"]
        target = np.array(eye["EyeControls3D:look_target"][0])
        position = np.array(eye["EyeControls3D:position"][0])
        np.testing.assert_allclose(target, centre, rtol=1e-5, atol=1e-4)
        offset = position - target
        assert offset[0] < 0 and offset[2] < 0          # south of and above the centre
        half = np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)) / 2
        # far enough that the sphere round the box fits in a 60 degree field of view
        assert np.linalg.norm(offset) >= max(half, 5.0) / np.sin(np.radians(30.0)) - 1e-6
    for i in range(1, N_VEH + 1):
        assert props[f"vehicle {i} error (m)"]["PlotLegend:visible"] == [False]


def test_fleet_trail_visible_time_range(fleet_written):
    path, _, _, _, _ = fleet_written
    ranges = read_rrd_visible_time_ranges(path)
    want = {
        "sim_time": (("cursor_relative", -round(TRAIL_S * 1e9)), ("cursor_relative", 0)),
        "step": (("cursor_relative", -round(TRAIL_S / FLEET_H)), ("cursor_relative", 0)),
    }
    # the trail entities carry a range (the rest of the 3D view shows the latest sample);
    # the per-vehicle plots show the whole run
    whole = {"sim_time": (("infinite", None), ("infinite", None)),
             "step": (("infinite", None), ("infinite", None))}
    assert ranges == {**{(f"fleet {m}", f"/world/{m}/trails"): want for m in FLEET_METHODS},
                      **{(f"vehicle {i} {g}", None): whole for i in range(1, N_VEH + 1)
                         for g in ("error (m)", "control (N)")}}


def test_fleet_many_vehicles_use_tabs(tmp_path):
    n = 10
    runs = make_fleet_runs(methods=("ideal",), steps=12, n=n, seed=5)
    fleet = make_fleet(n=n, edges=tuple((i, i + 1) for i in range(1, n)), pinned=(1,))
    path = tmp_path / "ten.rrd"
    write_rrd(path, runs, FLEET_H, recording_name="ten", fleet=fleet)
    tree = read_rrd_blueprint_tree(path)
    left, right = tree["contents"][1]["contents"]
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
    assert all(target is None for _, target in read_rrd_visible_time_ranges(path))
    tree = read_rrd_blueprint_tree(path)
    assert all(v["class"] in ("TimeSeries", "TextDocument") for v in _views(tree))
    with pytest.raises(KeyError):
        read_rrd_points(path, "world/kalman/vehicles")
    assert not any(e.startswith(("vehicles/", "leader/")) for e in read_rrd_scalars(path))
