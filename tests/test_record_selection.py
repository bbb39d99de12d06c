"""``--record``: a recording holds the chosen groups of outputs only (entities and blueprint
views, read back), the statistics every output; the chunks reach the writer reduced to what
it keeps (orchestrator.recording.chunks), the same whatever the chunks."""
from __future__ import annotations

import json
import pickle

import numpy as np
import pytest
from rerun.chunk import RrdReader

from orchestrator.cli import main
from orchestrator.recording import read_rrd_scalars, write_rrd
from orchestrator.recording.chunks import digest, spec_of
from orchestrator.recording.layout import FLEET_TRACE_KEYS
from orchestrator.recording.selection import FLEET_GROUPS, PAPER_GROUPS, Selection
from support.recording import FLEET_H, H, make_fleet, make_fleet_runs, make_runs
from support.rrd_readback import read_rrd_blueprint_views


def entities(path) -> set[str]:
    """Every entity path of the recording store (data and statics), without the leading
    slash, but the recording's own properties."""
    reader = RrdReader(path)
    out = set()
    for store in reader.recordings():
        for chunk in reader.stream(store=store):
            out.add(str(chunk.entity_path).lstrip("/"))
    return {e for e in out if not e.startswith("__")}


def test_a_selection_names_the_layouts_groups():
    s = Selection.of(True, ["error", "scene"])
    assert s.names() == ["error", "scene"] and s.has("scene") and not s.has("control")
    assert s.keys() == {"e", "x", "z", "attitude"}
    assert Selection.of(False, None).names() == list(PAPER_GROUPS)
    with pytest.raises(ValueError, match=r"'current' is not a group of the paper layout "
                                         r"\(error, state, control, disturbance"):
        Selection.of(False, ["error", "current"])
    with pytest.raises(ValueError, match="name at least one group"):
        Selection.of(True, [])
    # every fleet group's keys are traces a fleet run can give
    optional = {"attitude", "rpm", "rudder", "stern", "saturated", "setpoint", "link_age",
                "link_delivered", "link_lost", "link_in_flight"}
    assert {k for keys, _ in FLEET_GROUPS.values() for k in keys} <= set(FLEET_TRACE_KEYS) | optional


def test_a_paper_recording_of_two_groups(tmp_path):
    runs = make_runs()
    whole, part = tmp_path / "whole.rrd", tmp_path / "part.rrd"
    write_rrd(whole, runs, H, recording_name="all")
    info = write_rrd(part, runs, H, recording_name="two", record=["control", "measurement"])
    a, b = read_rrd_scalars(whole), read_rrd_scalars(part)
    assert set(b) == {k for k in a if k.startswith(("control/", "measurement/"))}
    for k in b:                                     # the same series, bit for bit
        assert all(np.array_equal(x, y) for x, y in zip(a[k], b[k])), k
    assert info["signals"] == len(b)
    views = read_rrd_blueprint_views(part)
    series = {n for n, (cls, _) in views.items() if cls == "TimeSeries"}
    assert series == {f"control-{i} (dimensionless)" for i in (1, 2)} | {"measurements"}
    assert not any(n.startswith(("error", "state")) for n in read_rrd_blueprint_views(part))


def test_a_fleet_recording_without_the_scene_or_errors(tmp_path):
    runs, fleet = make_fleet_runs(), make_fleet()
    path = tmp_path / "fleet.rrd"
    write_rrd(path, runs, FLEET_H, recording_name="controls", fleet=fleet,
              record=["control", "leader"])
    ents = entities(path)
    assert not any(e.startswith("world") for e in ents)
    assert {e.split("/")[2] for e in ents if e.startswith("vehicles/")} == {"control"}
    assert {e for e in ents if e.startswith("leader/")} == {f"leader/{m}" for m in runs}
    views = read_rrd_blueprint_views(path)
    assert not any(cls == "3D" or "error" in n for n, (cls, _) in views.items())
    assert {n for n in views if "control" in n} == {f"vehicle {i} control (N)" for i in (1, 2, 3)}


@pytest.mark.slow
def test_a_fleet_run_records_the_chosen_groups_and_every_statistic(tmp_path):
    full, part = tmp_path / "full", tmp_path / "part"
    common = ["run", "--scenario", "formation-4", "--T", "20", "--quiet"]
    assert main([*common, "--out", str(full)]) == 0
    assert main([*common, "--out", str(part), "--record", "error,scene"]) == 0
    a = json.loads((full / "summary.json").read_text())
    b = json.loads((part / "summary.json").read_text())
    assert b["methods"] == a["methods"]             # the statistics: every output
    assert b["rrd"]["recorded_groups"] == ["error", "scene"]
    # all of the fleet's groups that this run has (no links, actuators, set-points)
    assert a["rrd"]["recorded_groups"] == ["error", "control", "state", "current", "leader",
                                           "scene"]
    ents = entities(part / "formation-4.rrd")
    assert {e.split("/")[2] for e in ents if e.startswith("vehicles/")} == {"error"}
    assert {"world/kalman/vehicles", "world/kalman/trails", "world/kalman/edges"} <= ents
    assert not any(e.startswith(("leader/", "network/")) for e in ents)
    sa, sb = read_rrd_scalars(full / "formation-4.rrd"), read_rrd_scalars(part / "formation-4.rrd")
    assert set(sb) == {k for k in sa if "/error/" in k} and len(sb) == 4
    for k in sb:
        assert all(np.array_equal(x, y) for x, y in zip(sa[k], sb[k])), k
    views = read_rrd_blueprint_views(part / "formation-4.rrd")
    assert any(cls == "3D" for cls, _ in views.values())
    assert not any("control" in n for n in views)
    assert (part / "formation-4.rrd").stat().st_size < (full / "formation-4.rrd").stat().st_size


@pytest.mark.parametrize("argv, says", [
    (["--record", "errr"], "--record: 'errr' is not a group of the paper layout"),
    (["--scenario", "formation-4", "--record", "error,links"],
     "--record links: this run has no acoustic links, so no links to record"),
    (["--scenario", "formation-4", "--record", "rpm"],
     "--record: 'rpm' is not a group of the fleet layout"),
    (["--record", "error,,control"], "name the groups separated by commas"),
])
def test_a_bad_selection_is_refused_in_one_line(tmp_path, capsys, argv, says):
    try:
        status = main(["run", "--T", "2", "--out", str(tmp_path / "x"), *argv])
    except SystemExit as exc:                       # argparse's refusal
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert says in err[-1] and "Traceback" not in "\n".join(err)
    assert not (tmp_path / "x").exists()


def test_the_digest_keeps_the_recorded_rows_whatever_the_chunks():
    runs, fleet = make_fleet_runs(steps=263), make_fleet()
    traces = runs["kalman"]
    spec = spec_of(FLEET_TRACE_KEYS, FLEET_H, 10, Selection.of(True, ["error", "scene"]),
                   fleet.leader_output)
    whole = digest(spec, "kalman", 0, traces, False)
    cuts = [0, 7, 64, 65, 200, 263]
    parts = [digest(spec, "kalman", a, {k: v[a:b] for k, v in traces.items()}, False)
             for a, b in zip(cuts, cuts[1:])]
    assert np.array_equal(np.concatenate([p.ks for p in parts]), np.arange(0, 263, 10))
    assert set(whole.rows) == {"e", "x", "z"}
    for k in whole.rows:
        assert np.array_equal(np.concatenate([p.rows[k] for p in parts]), whole.rows[k])
        assert np.array_equal(whole.rows[k], traces[k][::10])
        lo = np.min([p.extremes[k][0] for p in parts], axis=0)
        assert np.array_equal(lo, traces[k].min(axis=0))      # extremes of every step
    # what crosses to the writer: a tenth of the rows, three of the seven keys
    sent = len(pickle.dumps(whole, protocol=pickle.HIGHEST_PROTOCOL))
    full = sum(np.asarray(v).nbytes for v in traces.values())
    assert sent < full / 10


def test_a_non_finite_column_keeps_its_finite_extremes():
    from orchestrator.recording.chunks import column_extremes
    a = np.array([[1.0, np.nan, np.inf], [-2.0, np.nan, 3.0]])
    lo, hi, flo, fhi, fin = column_extremes(a)
    assert lo[0] == -2.0 and hi[0] == 1.0 and np.isnan(lo[1]) and np.isnan(hi[1])
    assert flo[2] == 3.0 and fhi[2] == 3.0 and list(fin) == [True, False, True]


@pytest.mark.slow
def test_a_per_vehicle_run_over_links_records_its_links_alone(tmp_path):
    """Native FMUs, the compiled master, acoustic links: ``--record links`` holds the links'
    counts and each vehicle's age of information, nothing else; the figures are those of a
    full recording."""
    common = ["run", "--scenario", "formation-4", "--deployment", "per-vehicle",
              "--architecture", "distributed", "--latency", "0.5", "--period", "1",
              "--loss", "0.2", "--fmus", "native", "--master", "native", "--T", "10",
              "--quiet"]
    assert main([*common, "--out", str(tmp_path / "full")]) == 0
    assert main([*common, "--out", str(tmp_path / "links"), "--record", "links"]) == 0
    a = json.loads((tmp_path / "full" / "summary.json").read_text())
    b = json.loads((tmp_path / "links" / "summary.json").read_text())
    assert b["methods"] == a["methods"] and set(b["master"].values()) == {"native"}
    assert b["rrd"]["recorded_groups"] == ["links"]
    assert "links" in a["rrd"]["recorded_groups"]
    ents = entities(tmp_path / "links" / "formation-4.rrd")
    assert {e.split("/")[0] for e in ents} == {"network", "vehicles", "legend", "legend_links"}
    assert {e.split("/")[2] for e in ents if e.startswith("vehicles/")} == {"network"}
    sa = read_rrd_scalars(tmp_path / "full" / "formation-4.rrd")
    sb = read_rrd_scalars(tmp_path / "links" / "formation-4.rrd")
    assert set(sb) == {k for k in sa if k.startswith("network/") or "/network/" in k}
    for k in sb:
        assert all(np.array_equal(x, y) for x, y in zip(sa[k], sb[k])), k
    views = read_rrd_blueprint_views(tmp_path / "links" / "formation-4.rrd")
    assert not any("error" in n or "control" in n or cls == "3D" for n, (cls, _) in views.items())
    assert any("age" in n for n in views), sorted(views)
