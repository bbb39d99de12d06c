"""auv-cosim envelope: where the formation holds (orchestrator.running.envelope)."""
from __future__ import annotations

import json
import math

import pytest

from orchestrator.cli import main
from orchestrator.running.envelope import envelope_point
from orchestrator.scenario import load_scenario


def test_a_point_is_the_fleet_behind_a_line_or_a_circle_started_in_formation():
    sc = load_scenario("formation-4").with_run(T=20.0, deployment="per-vehicle",
                                               architecture="distributed")
    line = envelope_point(sc, 2.0, math.inf, 0.3)
    circle = envelope_point(sc, 1.5, 40.0, 0.1)
    assert line.fleet.leader.kind == "straight" and circle.fleet.leader.kind == "circle"
    assert line.fleet.spec["vehicles"][0]["current"]["sigma"] == 0.3
    assert line.T == 20.0 and line.deployment == "per-vehicle"
    # started in formation: each vehicle at the leader's position plus its offset
    z0 = line.fleet.leader.z0
    for v in line.fleet.spec["vehicles"]:
        assert v["x0"][:3] == pytest.approx([z0[0] + v["offset"][0], z0[1] + v["offset"][1],
                                             z0[2] + v["offset"][2]])


@pytest.mark.slow
def test_envelope_runs_the_grid_and_says_where_it_holds(tmp_path, capsys):
    out = tmp_path / "env"
    assert main(["envelope", "--scenario", "formation-4", "--deployment", "per-vehicle",
                 "--architecture", "distributed", "--T", "20", "--speeds", "1.5",
                 "--radii", "inf,30", "--currents", "0.1", "--tolerance", "2.5",
                 "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    pts = s["envelope"]["points"]
    assert s["envelope"]["tolerance_m"] == 2.5 and len(pts) == 2
    assert pts[0]["radius"] is None and pts[1]["radius"] == 30.0
    for p in pts:
        assert p["holds"] == (p["max_error"] <= 2.5) and p["max_error"] > 0
        assert (out / p["folder"] / "summary.json").exists()
    assert "points hold within 2.5 m" in capsys.readouterr().out


def test_bad_grids_are_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:            # argparse: usage line and status 2
        main(["envelope", "--scenario", "formation-4", "--deployment", "per-vehicle",
              "--radii", "inf,-5", "--out", str(tmp_path / "a")])
    assert exc.value.code == 2
    assert "every value must be a positive number (-5 is not)" in capsys.readouterr().err
    assert main(["envelope", "--scenario", "formation-4", "--out", str(tmp_path / "b")]) == 2
    assert "--deployment per-vehicle" in capsys.readouterr().err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


@pytest.mark.slow
def test_the_envelope_as_a_campaign_spec_gives_the_envelopes_figures(tmp_path, capsys):
    """envelope --write-spec writes the grid as a campaign spec; the campaign (a real Dask
    local cluster) gives, point by point, the envelope's max_error to 1e-12."""
    from support.campaign import rows
    grid = ["--scenario", "formation-4", "--deployment", "per-vehicle", "--architecture",
            "distributed", "--T", "10", "--speeds", "1.5", "--radii", "inf,30",
            "--currents", "0.1"]
    assert main(["envelope", *grid, "--out", str(tmp_path / "env")]) == 0
    spec = tmp_path / "env.toml"
    assert main(["envelope", *grid, "--write-spec", str(spec)]) == 0
    assert f"auv-cosim campaign {spec}" in capsys.readouterr().out
    assert main(["campaign", str(spec), "--workers", "1", "--out", str(tmp_path / "c")]) == 0
    table = sorted(rows(tmp_path / "c"), key=lambda r: r["point"])
    points = json.loads((tmp_path / "env" / "summary.json").read_text())["envelope"]["points"]
    assert len(table) == len(points) == 2
    for r, p in zip(table, points):
        assert r["status"] == "ok", r["error"]
        assert r["max_error"] == pytest.approx(p["max_error"], rel=1e-12)
        assert r["actuator_saturation_fraction"] == p["actuator_saturation_fraction"]


@pytest.mark.slow
def test_each_point_carries_the_path_check_beside_its_figures(tmp_path):
    """survey-4-remus (a [design] section) over 1 and 2 m/s straight in a 0.1 m/s current:
    at 1 m/s the rudder cannot give the controller's 3-sigma lateral acceleration at the
    slowest speed through the water (rejected, the reason named), at 2 m/s it can
    (feasible); the summary counts how the verdicts and the runs agree, and the campaign
    written from the same grid carries the same verdicts in its rows (a real Dask cluster)."""
    from support.campaign import rows
    grid = ["--scenario", "survey-4-remus", "--T", "4", "--speeds", "1,2", "--radii", "inf",
            "--currents", "0.1"]
    assert main(["envelope", *grid, "--out", str(tmp_path / "env")]) == 0
    env = json.loads((tmp_path / "env" / "summary.json").read_text())["envelope"]
    slow, fast = env["points"]
    assert slow["path_feasible"] is False and "lateral acceleration" in slow["path_findings"]
    assert fast["path_feasible"] is True and fast["path_findings"] is None
    v = env["path_check"]
    assert v["points_judged"] == 2 and v["feasible"] == 1
    assert v["agree"] == sum(p["path_feasible"] == p["holds"] for p in env["points"])
    spec = tmp_path / "env.toml"
    assert main(["envelope", *grid, "--write-spec", str(spec)]) == 0
    assert main(["campaign", str(spec), "--workers", "1", "--out", str(tmp_path / "c")]) == 0
    table = sorted(rows(tmp_path / "c"), key=lambda r: r["point"])
    assert [r["path_feasible"] for r in table] == [False, True]
    assert [r["max_error"] for r in table] == pytest.approx(
        [p["max_error"] for p in env["points"]], rel=1e-12)
