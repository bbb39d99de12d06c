"""Native (C) FMUs of the design (orchestrator.cosim.native, orchestrator.interop.native):
the closed loop with native controller and estimator equals the all-pythonfmu loop, the
native plant's noise has the designed covariance and gives the predicted cost, and the
FMUs validate, round-trip their state, refuse bad parameters and load from awkward paths."""
from __future__ import annotations

import dataclasses
import shutil
import zipfile

import numpy as np
import pytest
from lxml import etree

from orchestrator.cosim.master import run_system
from orchestrator.interop.native import native_system
from orchestrator.scenario import load_scenario
from orchestrator.workflow import build, scenario_system

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")


def _native(sc, tmp_path, kinds=None):
    system = scenario_system(sc)
    py = build(sc, tmp_path / "py")
    ns = (native_system(system, py, tmp_path / "native") if kinds is None else
          native_system(system, py, tmp_path / "native", kinds))
    return system, py, ns


def _assert_equal_traces(ref, got, rel=1e-12):
    assert set(ref) == set(got)
    for key in ref:
        scale = max(float(np.abs(ref[key]).max()), 1e-300)
        assert np.abs(ref[key] - got[key]).max() <= rel * scale, key


@pytest.mark.parametrize("estimator", ["kalman", "classical", "ideal"])
@pytest.mark.parametrize("tracking", ["lq", "regulator"])
def test_native_controller_and_estimator_equal_the_pythonfmu_loop(tmp_path, estimator,
                                                                  tracking):
    """The paper's loop: native controller and estimator with the pythonfmu plant equal the
    all-pythonfmu loop to 1e-12 of each signal's scale, in every estimator mode and both
    tracking laws."""
    sc = load_scenario("paper").with_run(T=20.0, estimator=estimator, tracking=tracking)
    system, py, ns = _native(sc, tmp_path, ("estimator", "controller"))
    ref, _, _ = run_system(system, py, sc.steps)
    got, _, _ = run_system(ns.system, ns.fmus, sc.steps)
    _assert_equal_traces(ref, got)
    assert ns.fmus["controller"].name == "AuvControllerNative.fmu"
    assert ns.fmus["plant"] == py["plant"]                     # the plant stays pythonfmu


@pytest.mark.parametrize("architecture, estimator", [
    ("distributed", "kalman"), ("distributed", "ideal"), ("centralized", "kalman")])
def test_per_vehicle_native_controllers_and_estimators_equal_the_pythonfmu_loop(
        tmp_path, architecture, estimator):
    """formation-4 per vehicle: one native FMU per kind, each vehicle's own values as
    parameters (offsets, slot weights, rows of the stacked gain), equal to the pythonfmu
    loop to 1e-12."""
    sc = load_scenario("formation-4").with_run(
        T=20.0, deployment="per-vehicle", architecture=architecture, estimator=estimator)
    system, py, ns = _native(sc, tmp_path, ("vehicle_estimator", "vehicle_controller",
                                            "central_controller"))
    ref, _, _ = run_system(system, py, sc.steps)
    got, _, _ = run_system(ns.system, ns.fmus, sc.steps)
    _assert_equal_traces(ref, got)
    ctrl = [c for c in ns.system.components if c.name.startswith("controller_")]
    assert len(ctrl) == 4 and ctrl[0].parameters == {}       # the start values: vehicle 1
    assert all(c.parameters for c in ctrl[1:])                # the others' own values


def _with_plant_seed(system, seed):
    return dataclasses.replace(system, components=tuple(
        dataclasses.replace(c, parameters={**c.parameters, "seed": seed})
        if c.fmu == "plant" else c for c in system.components))


def test_the_native_plant_noise_has_the_designed_covariance(tmp_path):
    """The all-native loop; the plant draws its own normals (xoshiro256**, polar method):
    over 40,000 steps the measurement noise y - C x has the covariance Rd and the process
    noise s+ - Ad s - Bd u the covariance Qd, within 5 standard errors; the same seed
    gives the same numbers, another seed others."""
    sc = load_scenario("paper").with_run(T=400.0, h=0.01)
    _, _, ns = _native(sc, tmp_path)
    form = ns.forms["plant"]
    tr, _, _ = run_system(ns.system, ns.fmus, sc.steps)

    def close(samples, cov):
        got = np.cov(samples.T)
        se = np.sqrt((cov ** 2 + np.outer(np.diag(cov), np.diag(cov))) / samples.shape[0])
        return np.all(np.abs(got - cov) <= 5 * se + 1e-300)

    Cq, Lr = form.role("C").matrix, form.role("G").matrix
    meas = Lr.shape[0]
    s = np.hstack([tr["x"], tr["w"], tr["z"]])
    n = np.hstack([tr["y"], tr["ybar"]])[:, :meas] - s @ Cq[:meas].T
    assert close(n, Lr @ Lr.T)
    Ad, Bd, Lq = (form.role(k).matrix for k in ("A", "B", "F"))
    v = s[1:] - s[:-1] @ Ad.T - tr["u"][:-1] @ Bd.T
    assert close(v, Lq @ Lq.T) and np.abs(v).max() > 0
    again, _, _ = run_system(ns.system, ns.fmus, 100)
    assert np.array_equal(again["y"], tr["y"][:100])
    third, _, _ = run_system(_with_plant_seed(ns.system, 7), ns.fmus, 100)
    assert not np.array_equal(third["y"], tr["y"][:100])


@pytest.mark.slow
def test_the_all_native_loop_gives_the_predicted_cost(tmp_path):
    """The paper's loop, every FMU native (the plant's noise its own): the cost rate over
    8 seeds agrees with the Lyapunov prediction within 4 standard errors."""
    from controller_fmu.regulator import tracking_law
    from estimator_fmu.estimators import make_estimator
    from orchestrator.analysis.prediction import method_predictions
    from orchestrator.analysis.summary import run_stats
    from plant_model.discretization import discretize
    sc = load_scenario("paper").with_run(T=150.0)
    system, py, ns = _native(sc, tmp_path)
    model = discretize(sc.system, sc.h)
    _, window, from_start, k0 = method_predictions(
        sc, model, make_estimator(sc.system, model, sc.estimator),
        tracking_law(sc.system, sc.tracking).Ks)
    pred = (from_start or window).cost_rate
    costs = []
    for seed in range(8):
        tr, _, _ = run_system(_with_plant_seed(ns.system, seed), ns.fmus, sc.steps)
        costs.append(run_stats(tr, sc.system.Q, sc.system.R, k0, None)["cost_rate"])
    costs = np.array(costs)
    se = costs.std(ddof=1) / np.sqrt(costs.size)
    assert abs(costs.mean() - pred) < 4 * se, (costs.mean(), se, pred)


def test_native_fmus_validate_and_ship_their_sources(tmp_path):
    """fmpy validates every native FMU clean; needsExecutionTool false; the sources are in
    sources/ and listed; the binary needs only libc and libm."""
    import subprocess

    from fmpy import read_model_description
    from fmpy.validation import validate_fmu
    sc = load_scenario("formation-4").with_run(deployment="per-vehicle",
                                               architecture="distributed")
    _, _, ns = _native(sc, tmp_path)
    for key in ("leader", "vehicle", "vehicle_estimator", "vehicle_controller"):
        path = ns.fmus[key]
        assert validate_fmu(str(path)) == [], key
        md = read_model_description(str(path))
        cs = md.coSimulation
        assert not cs.needsExecutionTool and cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
        with zipfile.ZipFile(path) as z:
            names = set(z.namelist())
            root = etree.fromstring(z.read("modelDescription.xml"))
            assert [f.get("name") for f in root.iterfind("CoSimulation/SourceFiles/File")] == [
                "linear_fmu.c"]
            assert {"sources/linear_fmu.c", "sources/native_model.h",
                    "sources/fmi2Functions.h", f"binaries/linux64/{path.stem}.so"} <= names
            lib = tmp_path / f"{path.stem}.so"
            lib.write_bytes(z.read(f"binaries/linux64/{path.stem}.so"))
        needed = subprocess.run(["ldd", str(lib)], capture_output=True, text=True).stdout
        libs = {ln.split()[0] for ln in needed.splitlines() if "=>" in ln}
        assert libs <= {"libm.so.6", "libc.so.6"}, libs
