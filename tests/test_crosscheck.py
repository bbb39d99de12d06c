"""Cross-check reference files: real FMUs, one real closed loop, each FMU replayed alone with fmpy.

Tolerance of every replay: max |fmpy result - _ref.csv| <= 1e-12 (absolute; the signals are
of order 0.1 to 50). The replay runs the same FMU code on the same inputs, and the CSV
numbers round-trip exactly, so the difference measured here is 0.0.
"""
from __future__ import annotations

import json
import time

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.cross_check.validate_vendor_repo import validate_test_fmu
from fmpy.util import read_csv, read_ref_opt_file

from orchestrator.interop.crosscheck import (
    EPS_FRACTION,
    compare,
    hold_rows,
    replay,
    sample_after_inputs,
    write_crosscheck,
    write_csv,
)
from orchestrator.running import scenario_config
from support.loop import run_cosimulation

TOL = 1e-12
STEPS = 500
MODELS = {"plant": "AuvPlant", "estimator": "AuvEstimator", "controller": "AuvController"}
#: FMUs with direct feedthrough: replayed with the sample-after-inputs callback
FEEDTHROUGH = {"plant": False, "estimator": True, "controller": True}


@pytest.fixture(scope="module")
def fmus(paper_fmus):
    return paper_fmus


@pytest.fixture(scope="module")
def xc(paper, fmus, tmp_path_factory):
    # the cross-check repository's layout, so fmpy's own vendor-repo validator applies
    out = tmp_path_factory.mktemp("xc") / "fmus" / "2.0" / "cs" / "linux64" / "auv-cosim" / "0"
    return out, write_crosscheck(fmus, scenario_config(paper), out, steps=STEPS)


def _samples(signals: np.ndarray) -> np.ndarray:
    """The value of each sample from a hold-layout input table (rows 0, 2, 4, ... are at
    t = 0, h, 2 h, ... and hold the value set then, in both layouts)."""
    return signals[0::2]


def _run(files: dict, key: str, signals=None, start_values=None, hook=None) -> np.ndarray:
    """Replay one FMU alone: fmpy.simulate_fmu with the files' input, times and outputs."""
    opt = read_ref_opt_file(str(files["opt"]))
    ref = read_csv(files["ref"])
    if signals is None:
        signals = read_csv(files["in"])
    md = read_model_description(str(files["fmu"]))
    if hook is None:
        hook = FEEDTHROUGH[key]
    return simulate_fmu(
        str(files["fmu"]), start_time=opt["StartTime"], stop_time=opt["StopTime"],
        output_interval=opt["StepSize"], relative_tolerance=opt["RelTol"],
        input=signals, output=list(ref.dtype.names[1:]), start_values=start_values or {},
        model_description=md, step_finished=sample_after_inputs(signals, md) if hook else None)


def test_files_follow_the_cross_check_rules(xc, paper):
    out, paths = xc
    h = paper.h
    t = np.arange(STEPS) * h
    for key, model in MODELS.items():
        files = paths[key]
        assert files["in"].name == f"{model}_in.csv" and files["ref"].name == f"{model}_ref.csv"
        assert files["opt"].name == f"{model}_ref.opt" and files["in"].parent.name == model
        md = read_model_description(str(files["fmu"]))
        inputs = [v.name for v in md.modelVariables if v.causality == "input"]
        outputs = [v.name for v in md.modelVariables if v.causality == "output"]
        assert files["in"].read_text().splitlines()[0] == ",".join(
            f'"{n}"' for n in ["time", *inputs])
        assert files["ref"].read_text().splitlines()[0] == ",".join(
            f'"{n}"' for n in ["time", *outputs])
        sig = read_csv(files["in"], variable_names=inputs)
        ref = read_csv(files["ref"], variable_names=outputs)
        # reference: one row per sample k h; inputs: value k at k h and (k+1) h - eps
        assert np.array_equal(ref["time"], t)
        eps = EPS_FRACTION * h
        assert np.array_equal(sig["time"], np.concatenate(
            [[0.0], np.column_stack([t[1:] - eps, t[1:]]).ravel()]))
        assert np.all(np.diff(sig["time"]) > 0)
        for name in inputs:      # held: the row before each sample repeats the previous one
            assert np.array_equal(sig[name][1::2], sig[name][0:-1:2])
        opt = read_ref_opt_file(str(files["opt"]))
        assert opt == {"StartTime": 0.0, "StopTime": t[-1], "StepSize": h, "RelTol": 1e-9,
                       "OutputIntervalLength": h}
        # fmpy's validator of a vendor's cross-check directory: no problem
        assert validate_test_fmu(str(files["in"].parent)) == []
        for f in ("in", "ref", "opt"):
            assert files[f].stat().st_size < 1e6
    manifest = json.loads((out / "crosscheck.json").read_text())
    assert all(not manifest["fmus"][k]["start_values"] for k in MODELS)
    assert manifest["fmus"]["plant"]["direct_feedthrough_outputs"] == []
    assert manifest["fmus"]["controller"]["direct_feedthrough_outputs"] == ["u[1]", "u[2]"]


def test_files_hold_exactly_what_each_fmu_received_and_produced(xc, paper, fmus):
    _, paths = xc
    tr = run_cosimulation(fmus, scenario_config(paper), mode=paper.estimator, seed=paper.seed,
                          steps=STEPS).traces
    truth_connected = paper.estimator == "ideal"
    for key in MODELS:
        sig = _samples(read_csv(paths[key]["in"]))
        ref = read_csv(paths[key]["ref"])
        for name in sig.dtype.names[1:]:
            base, i = name[:-1].split("[")
            if key == "estimator" and base in ("x", "w", "z") and not truth_connected:
                assert np.all(sig[name] == 0.0), name     # never set: the start value
            else:
                assert np.array_equal(sig[name], tr[base][:, int(i) - 1]), (key, name)
        for name in ref.dtype.names[1:]:
            base, i = name[:-1].split("[")
            assert np.array_equal(ref[name], tr[base][:, int(i) - 1]), (key, name)


@pytest.mark.parametrize("key, hook", [("plant", False), ("plant", True),
                                       ("estimator", True), ("controller", True)])
def test_each_fmu_alone_reproduces_its_reference(xc, key, hook):
    _, paths = xc
    t0 = time.perf_counter()
    res = _run(paths[key], key, hook=hook)
    wall = time.perf_counter() - t0
    diff = compare(res, read_csv(paths[key]["ref"]))
    print(f"{key} (sample after inputs: {hook}): max diff {max(diff.values()):.3g}, "
          f"replay {wall:.3f} s")
    assert max(diff.values()) <= TOL, diff


def test_fmpy_plain_sampling_sees_feedthrough_outputs_one_input_late(xc):
    """Without the callback fmpy samples after fmi2DoStep(t, h), before the inputs of t + h:
    the controller's u at (k+1) h is u[k] (exactly), the estimator's estimate is off."""
    _, paths = xc
    ref = read_csv(paths["controller"]["ref"])
    res = _run(paths["controller"], "controller", hook=False)
    for n in ("u[1]", "u[2]"):
        assert res[n][0] == ref[n][0]
        assert np.array_equal(res[n][1:], ref[n][:-1])
        assert np.max(np.abs(res[n] - ref[n])) > 0.1
    est = _run(paths["estimator"], "estimator", hook=False)
    assert max(compare(est, read_csv(paths["estimator"]["ref"])).values()) > 1e-2


@pytest.mark.parametrize("key", list(MODELS))
def test_inputs_one_step_late_do_not_reproduce_the_reference(xc, key, tmp_path):
    _, paths = xc
    ref = read_csv(paths[key]["ref"])
    samples = _samples(read_csv(paths[key]["in"]))
    names = list(samples.dtype.names[1:])
    values = np.column_stack([samples[n] for n in names])
    t = samples["time"]
    late = np.vstack([values[:1], values[:-1]])          # sample k gets the value of k - 1
    for vals, label in ((values, "same"), (late, "late")):
        path = tmp_path / f"{label}_in.csv"
        write_csv(path, names, *hold_rows(t, vals))
        diff = max(compare(_run(paths[key], key, signals=read_csv(path)), ref).values())
        if label == "same":
            assert diff <= TOL          # the rewrite itself is faithful
        else:
            assert diff > 1e-3, f"{key}: inputs one step late still match ({diff})"


def test_seed_and_mode_other_than_built_are_start_values_to_set(paper, fmus, tmp_path):
    steps = 60
    paths = write_crosscheck(fmus, scenario_config(paper), tmp_path, steps=steps, seed=7,
                             mode="ideal")
    manifest = json.loads((tmp_path / "crosscheck.json").read_text())
    sv = {k: manifest["fmus"][k]["start_values"] for k in MODELS}
    assert sv == {"plant": {"seed": 7}, "estimator": {"mode": "ideal"}, "controller": {}}
    assert "seed` = `7`" in paths["plant"]["readme"].read_text()
    tr = run_cosimulation(fmus, scenario_config(paper), mode="ideal", seed=7, steps=steps).traces
    sig = _samples(read_csv(paths["estimator"]["in"]))
    assert np.array_equal(sig["z[2]"], tr["z"][:, 1])     # the truth is connected in 'ideal'
    for key in MODELS:
        ref = read_csv(paths[key]["ref"])
        res = replay(paths[key]["fmu"], paths[key]["opt"], paths[key]["in"],
                     list(ref.dtype.names[1:]), start_values=sv[key])
        assert max(compare(res, ref).values()) <= TOL, key
    # without the seed the plant draws other noise: no match
    ref = read_csv(paths["plant"]["ref"])
    res = replay(paths["plant"]["fmu"], paths["plant"]["opt"], paths["plant"]["in"],
                 list(ref.dtype.names[1:]))
    assert max(compare(res, ref).values()) > 1e-3


def test_repeated_time_stamp_layout_also_reproduces_in_fmpy(paper, fmus, tmp_path):
    """layout='repeat' (a repeated time stamp at each sample): fmpy takes the value after it
    (apply(t, after_event=True)), so the replay matches too."""
    paths = write_crosscheck(fmus, scenario_config(paper), tmp_path, steps=100, layout="repeat")
    for key in MODELS:
        sig = read_csv(paths[key]["in"])
        t = np.arange(100) * paper.h
        assert np.array_equal(sig["time"], np.concatenate([[0.0], np.repeat(t[1:], 2)]))
        diff = compare(_run(paths[key], key), read_csv(paths[key]["ref"]))
        assert max(diff.values()) <= TOL, (key, diff)
