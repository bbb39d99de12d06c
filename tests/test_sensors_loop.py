"""[sensors] in a fleet scenario: the vehicle FMUs report fixes, DVL and depth at their
rates, the estimator FMUs run the multi-rate filter; the linear and the nonlinear vehicle."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from estimator_fmu.multirate import MultiRateKalman, navigation_estimator
from orchestrator.cli import main
from orchestrator.cosim.build import build_fmus
from orchestrator.cosim.master import run_system
from orchestrator.cosim.per_vehicle import build_configs, per_vehicle_configs, per_vehicle_system
from orchestrator.scenario import ScenarioError, load_scenario
from plant_model.linalg_checks import ModelError
from plant_model.navigation import NavigationSensors
from plant_model.per_vehicle import sample_vehicle

BUILTIN = Path(__file__).parent.parent / "orchestrator/scenario/builtin/formation-4.toml"
SENSORS = '\n[sensors]\nkind = "remus"\nfix_period = 1.0\nfix_dropout = 0.2\n'


def _scenario(tmp_path, model="remus100-6dof", extra=SENSORS, per_vehicle=True):
    text = BUILTIN.read_text().replace('model = "remus100"', f'model = "{model}"')
    if per_vehicle:
        text = text.replace('tracking = "regulator"', 'tracking = "regulator"\n'
                            'deployment = "per-vehicle"\narchitecture = "distributed"')
    path = tmp_path / f"{model}.toml"
    path.write_text(text + extra)
    return path


@pytest.mark.slow
@pytest.mark.parametrize("model", ["remus100", "remus100-6dof"])
def test_the_estimator_fmu_is_the_multirate_filter_on_the_vehicle_reports(tmp_path, model):
    sc = load_scenario(_scenario(tmp_path, model)).with_run(T=8.0)
    cfgs = per_vehicle_configs(sc, "distributed", estimator="kalman", seed=1, tracking=sc.tracking)
    fmus = build_fmus(None, tmp_path / "fmus", kinds=build_configs(cfgs))
    system = per_vehicle_system(sc, cfgs, "distributed")
    traces, _, _ = run_system(system, fmus, sc.steps)
    names = system.trace_names()
    nav = traces[names[("vehicle_3", "nav")]]
    k = np.arange(sc.steps)
    assert np.all(nav[k % 100 != 0, 7] == 0) and 0 < nav[k % 100 == 0, 7].sum() <= 8
    assert np.all(nav[k % 20 == 0, 8] + (nav[k % 20 == 0, 8] == 0) >= 1)
    assert nav[:, 9].sum() == sc.steps // 10                      # depth: 10 Hz, no dropout
    view = sc.fleet.views[2]
    kf = MultiRateKalman(sample_vehicle(view, sc.h, 3), NavigationSensors(
        fix_period=1.0, fix_dropout=0.2), np.concatenate([view.x0, view.w0]))
    u = traces[names[("controller_3", "u")]]
    est = np.hstack([traces[names[("estimator_3", "xhat")]],
                     traces[names[("estimator_3", "what")]]])
    worst = 0.0
    for j in range(sc.steps):
        e = kf.estimate(np.concatenate([nav[j], np.zeros(9)]))
        worst = max(worst, float(np.abs(e - est[j]).max()))
        kf.update(e, u[j])
    assert worst < 1e-9
    truth = traces[names[("vehicle_3", "x")]]
    assert np.abs(est[200:, :3] - truth[200:, :3]).max() < 2.0     # it follows the vehicle


def test_sensors_are_refused_where_they_cannot_be(tmp_path, capsys):
    with pytest.raises(ScenarioError, match=r'\[sensors\] needs \[simulation\] deployment = '
                                            r'"per-vehicle"'):
        load_scenario(_scenario(tmp_path, "remus100", per_vehicle=False)).with_run(T=1.0)
    with pytest.raises(ScenarioError, match=r"dvl_period = 0.015 s is not a whole number"):
        load_scenario(_scenario(tmp_path, extra=SENSORS + "dvl_period = 0.015\n"))
    with pytest.raises(ScenarioError, match=r"kind = 'gps' is not one of position, remus"):
        load_scenario(_scenario(tmp_path, extra='\n[sensors]\nkind = "gps"\n'))
    path = _scenario(tmp_path)
    assert main(["run", "--scenario", str(path), "--estimator", "classical", "--T", "1",
                 "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err.strip()
    assert "needs estimator kalman or ideal, not 'classical'" in err
    assert len(err.splitlines()) == 1
    assert not (tmp_path / "c").exists()
    sc = load_scenario(path)
    view = sc.fleet.views[0]
    with pytest.raises(ModelError, match="needs a position fix every step"):
        navigation_estimator(view, sample_vehicle(view, sc.h, 1), "classical",
                             NavigationSensors())


@pytest.mark.slow
def test_a_run_with_sensors_says_there_is_no_prediction(tmp_path):
    out = tmp_path / "run"
    assert main(["run", "--scenario", str(_scenario(tmp_path, "remus100")), "--T", "20",
                 "--out", str(out), "--quiet"]) == 0
    m = json.loads((out / "summary.json").read_text())["methods"]["kalman"]
    assert m["cost_rate"]["predicted"] is None and "multi-rate" in m["prediction_note"]
    assert m["max_error"] < 5.0 and m["actuator_saturation_fraction"] is None
