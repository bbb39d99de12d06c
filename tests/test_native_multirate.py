"""The native multi-rate navigation filter (AuvVehicleEstimatorNative of a [sensors] run,
fmu_common/native/multirate_fmu.c) against the pythonfmu AuvVehicleEstimator it replaces:
over a drive with random dropouts of every sensor both give the same estimate to 1e-12 of
its scale; the FMU validates, restores its state bit for bit, and refuses a bad parameter
naming it; `--fmus native` runs a REMUS 100 survey with it to the pythonfmu run's traces."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from orchestrator.cosim.instance import CosimError, Extracted, FmuInstance
from orchestrator.cosim.native_multirate import native_multirate_fmu
from orchestrator.running.systems import build, scenario_system
from orchestrator.scenario import load_scenario

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """survey-4-remus's vehicle 2 estimator: pythonfmu and native, with its parameters."""
    folder = tmp_path_factory.mktemp("multirate")
    sc = load_scenario("survey-4-remus").with_run(T=2.0)
    comp = next(c for c in scenario_system(sc).components if c.name == "estimator_2")
    py = build(sc, folder / "py")["vehicle_estimator"]
    nat, _, kf = native_multirate_fmu(py, comp.parameters, folder / "native", 2.0)
    ex = Extracted({"py": py, "nat": nat})
    yield {"py": py, "nat": nat, "params": comp.parameters, "h": kf[7]}, ex
    ex.cleanup()


def _open(pair, key, name, **override):
    info, ex = pair
    inst = FmuInstance("estimator", info[key], ex.dirs[key], name)
    inst.initialize({**(info["params"] if key == "py" else {}), **override}, T=100.0)
    return inst


def _drive(inst, steps, h, seed, k0=0):
    """Fixes, DVL and depth (noisy, moving) with each sensor's valid flag drawn at 1/2;
    random x, w, u: the outputs per step."""
    names = [v.name for v in inst.md.modelVariables if v.causality == "input"]
    vin = [inst.vr[n] for n in names]
    vout = [inst.vr[v.name] for v in inst.md.modelVariables if v.causality == "output"]
    r = np.random.default_rng(seed)
    rec = []
    for k in range(k0, k0 + steps):
        row = r.standard_normal(len(names))
        row[:3] = 5.0 * row[:3] + 0.5 * k * h
        row[7:10] = r.random(3) < 0.5
        inst.slave.setReal(vin, list(row))
        rec.append(inst.slave.getReal(vout))
        inst.slave.doStep(k * h, h)
    return np.array(rec)


def test_the_native_filter_equals_the_pythonfmu_filter_with_dropouts(pair):
    h = pair[0]["h"]
    out = {}
    for key in ("py", "nat"):
        inst = _open(pair, key, f"eq{key}")
        out[key] = _drive(inst, 800, h, seed=5)
        inst.close()
    scale = np.max(np.abs(out["py"]), axis=0)
    err = np.max(np.abs(out["nat"] - out["py"]) / scale)
    assert err <= 1e-12, err
    assert np.all(np.std(out["nat"], axis=0) > 0)           # every estimate moved
    what = out["nat"][:, -3:]
    assert np.max(np.abs(what)) <= 1.0                      # the current clipped to 1 m/s


def test_the_native_filter_validates_and_restores_its_state_bit_for_bit(pair):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(pair[0]["nat"])) == []
    h = pair[0]["h"]
    inst = _open(pair, "nat", "state")
    _drive(inst, 100, h, seed=6)
    state = inst.slave.getFMUState()
    first = _drive(inst, 200, h, seed=7, k0=100)
    inst.slave.setFMUState(state)
    assert np.array_equal(_drive(inst, 200, h, seed=7, k0=100), first)
    inst.slave.setFMUState(inst.slave.deserializeFMUState(inst.slave.serializeFMUState(state)))
    assert np.array_equal(_drive(inst, 200, h, seed=7, k0=100), first)
    inst.slave.freeFMUState(state)
    inst.close()


@pytest.mark.parametrize("name, value, fragment", [
    ("Rd[4]", 0.0, "parameter Rd[4] = 0 must be a positive variance"),
    ("P0[1,2]", 7.0, "parameter P0 is not symmetric: P0[2,1] differs from P0[1,2]"),
    ("current_max", -1.0, "parameter current_max = -1 m/s must be positive"),
])
def test_a_bad_parameter_fails_initialization_naming_it(pair, name, value, fragment):
    with pytest.raises(CosimError) as exc:
        _open(pair, "nat", f"bad{name}", **{name: value})
    assert "initialization failed" in str(exc.value) and fragment in str(exc.value)


@pytest.mark.slow
def test_a_remus_survey_runs_native_with_the_filter_to_the_pythonfmu_traces(tmp_path):
    from orchestrator.cli import main
    from orchestrator.recording import read_rrd_scalars
    got = {}
    for fm in ("python", "native"):
        out = tmp_path / fm
        assert main(["run", "--scenario", "survey-4-remus", "--T", "3", "--seed", "3",
                     "--quiet", "--out", str(out), "--fmus", fm]) == 0
        s = json.loads((out / "summary.json").read_text())
        got[fm] = (s, read_rrd_scalars(out / f"{s['scenario']}.rrd"))
    kinds = {k: e["kind"] for k, e in got["native"][0]["fmus"].items()}
    assert set(kinds.values()) == {"native"}, kinds    # the filter and the 6-DOF vehicles
    ref, nat = got["python"][1], got["native"][1]
    assert set(ref) == set(nat)
    for entity, (_, _, values) in ref.items():
        scale = max(float(np.nanmax(np.abs(values))), 1e-300)
        assert np.nanmax(np.abs(nat[entity][2] - values)) <= 1e-12 * scale, entity
