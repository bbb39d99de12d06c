"""compare --what plants: the linear and the nonlinear REMUS 100 under the same FMUs
(orchestrator.running.plants), and the nonlinear model in a scenario file."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from orchestrator.cli import main
from support.cli import assert_one_line_error

BUILTIN = Path(__file__).parent.parent / "orchestrator/scenario/builtin/formation-4.toml"


@pytest.mark.slow
def test_compare_plants_reports_errors_by_segment_and_saturation(tmp_path, capsys):
    out = tmp_path / "plants"
    assert main(["compare", "--scenario", "formation-4", "--deployment", "per-vehicle",
                 "--architecture", "distributed", "--what", "plants", "--seeds", "0",
                 "--T", "30", "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    s = json.loads((out / "summary.json").read_text())
    lin, six = s["methods"]["remus100"], s["methods"]["remus100-6dof"]
    assert lin["actuator_saturation_fraction"] is None          # no actuators to saturate
    assert 0.0 < six["actuator_saturation_fraction"] <= 1.0
    for m in (lin, six):
        assert m["max_error"] >= max(m["max_error_straight"] or 0, m["max_error_turns"] or 0)
        assert m["max_error"] > 0 and 0.0 <= m["turn_fraction"] <= 1.0
    # the torpedo cannot follow the 2.3 m/s start of the survey as the linear model does
    assert six["max_error"] > lin["max_error"]
    assert six["plant"] == "remus100-6dof" and s["plants"]["remus100"]["folder"] == "remus100"
    assert "linear design model" in six["prediction_note"] and "prediction_note" not in lin
    for model in ("remus100", "remus100-6dof"):
        assert (out / model / "formation-4.rrd").stat().st_size > 10_000
        assert json.loads((out / model / "summary.json").read_text())["methods"]
    sub = json.loads((out / "remus100-6dof" / "summary.json").read_text())
    assert set(sub["fmus"]) == {"leader", "remus6dof", "vehicle_estimator",
                                "vehicle_controller"}
    assert "remus100-6dof" in printed and "saturated" in printed
    _recording_shows_hulls_and_actuators(out / "remus100-6dof" / "formation-4.rrd")


def _recording_shows_hulls_and_actuators(rrd):
    """The .rrd read back: per vehicle rpm and fin series, and oriented hulls (unit
    quaternions) at the vehicles' positions in the 3D scene."""
    import numpy as np

    from orchestrator.recording.reader import _entity_rows, read_rrd_points, read_rrd_series
    _, _, rpm = read_rrd_series(rrd, "vehicles/2/propeller/kalman")
    _, _, fins = read_rrd_series(rrd, "vehicles/2/fins/kalman")
    assert rpm.shape[1] == 1 and 0 < rpm.max() <= 1525.0 and fins.shape[1] == 2
    assert np.abs(fins).max() <= np.radians(30.0) + 1e-9 and np.ptp(fins[:, 0]) > 0
    step, _, quats = _entity_rows(rrd, "world/kalman/hulls", "Ellipsoids3D:quaternions")
    q = np.concatenate([np.asarray(c.flatten().flatten().to_numpy(zero_copy_only=False))
                        for c in quats]).reshape(-1, 4)
    assert q.shape[0] == 4 * step.size and np.allclose(np.linalg.norm(q, axis=1), 1, atol=1e-6)
    assert np.ptp(q[:, 3]) > 0.01                                  # the hulls turn
    _, _, centers = _entity_rows(rrd, "world/kalman/hulls", "Ellipsoids3D:centers")
    _, _, pos = read_rrd_points(rrd, "world/kalman/vehicles")
    c = np.concatenate([np.asarray(x.flatten().flatten().to_numpy(zero_copy_only=False))
                        for x in centers]).reshape(-1, 4, 3)
    assert c.shape == pos.shape and np.allclose(np.sort(c.ravel()), np.sort(pos.ravel()))


def test_the_nonlinear_vehicle_is_refused_where_it_cannot_run(tmp_path, capsys):
    def one_line(argv, *fragments):
        assert_one_line_error(capsys, argv, *fragments)
    text = BUILTIN.read_text().replace('model = "remus100"', 'model = "remus100-6dof"')
    (tmp_path / "six.toml").write_text(text)
    one_line(["run", "--scenario", str(tmp_path / "six.toml"), "--out", str(tmp_path / "a")],
             'remus100-6dof needs [simulation] deployment = "per-vehicle"')
    one_line(["compare", "--scenario", "formation-4", "--what", "plants",
              "--out", str(tmp_path / "b")], "add --deployment per-vehicle")
    bad = text.replace("params = { cruise_speed = 1.5 }", "params = { n_max = -1525.0 }")
    (tmp_path / "bad.toml").write_text(bad)
    one_line(["run", "--scenario", str(tmp_path / "bad.toml"), "--deployment", "per-vehicle",
              "--out", str(tmp_path / "c")], "n_max = -1525 rpm must be positive")
    sub = text.replace("params = { cruise_speed = 1.5 }", "params = { substep = 0.003 }")
    (tmp_path / "sub.toml").write_text(sub)
    one_line(["run", "--scenario", str(tmp_path / "sub.toml"), "--deployment", "per-vehicle",
              "--out", str(tmp_path / "d")],
             "vehicle 1: remus100-6dof: substep = 0.003 s does not divide the step h = 0.01 s")
    assert not any((tmp_path / d).exists() for d in "abcd")
