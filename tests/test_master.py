"""The fmpy master over the real FMUs: exact loop, reproducibility, errors as statuses."""
from __future__ import annotations

import ctypes
import gc
from contextlib import contextmanager

import numpy as np
import pytest

from estimator_fmu.registry import ESTIMATOR_MODES
from orchestrator.analysis.reference import run_monolithic
from orchestrator.cosim.instance import CosimError, Extracted, FmuInstance
from orchestrator.running import scenario_config
from support.loop import fmu_parameters, run_cosimulation


@pytest.fixture(scope="module")
def fmus(paper_fmus):
    return paper_fmus


@pytest.mark.parametrize("mode", ESTIMATOR_MODES)
def test_cosimulation_reproduces_monolithic_loop(paper, fmus, mode):
    steps = 3000
    res = run_cosimulation(fmus, scenario_config(paper), mode=mode, seed=4, steps=steps)
    ref = run_monolithic(paper.system, paper.h, mode, 4, steps)
    for key, arr in ref.items():
        np.testing.assert_allclose(res.traces[key], arr, rtol=0, atol=1e-9, err_msg=key)
    # the loop really ran: noise made the traces move
    assert np.std(res.traces["e"][:, 0]) > 0.1


@pytest.mark.slow
@pytest.mark.parametrize("mode", ESTIMATOR_MODES)
def test_cosimulation_reproduces_monolithic_loop_full_paper_run(paper, fmus, mode):
    res = run_cosimulation(fmus, scenario_config(paper), mode=mode, seed=0, steps=paper.steps)
    ref = run_monolithic(paper.system, paper.h, mode, 0, paper.steps)
    assert max(float(np.max(np.abs(res.traces[k] - ref[k]))) for k in ref) < 1e-9


def test_same_seed_same_traces_other_seed_other_traces(paper, fmus):
    cfg = scenario_config(paper)
    a = run_cosimulation(fmus, cfg, mode="kalman", seed=11, steps=500)
    b = run_cosimulation(fmus, cfg, mode="kalman", seed=11, steps=500)
    c = run_cosimulation(fmus, cfg, mode="kalman", seed=12, steps=500)
    for k in a.traces:
        assert np.array_equal(a.traces[k], b.traces[k]), k
    assert not np.allclose(a.traces["y"], c.traces["y"])


def test_parameters_set_by_the_host_are_used(paper, fmus):
    """FMUs built for the paper; the host changes Q, x0 and h: the FMUs follow."""
    changed = paper.system.with_changes(Q=[[10.0, 0.0], [0.0, 10.0]], x0=[1.0, -1.0])
    sc = paper.with_run(h=0.02)
    from dataclasses import replace
    sc = replace(sc, system=changed)
    res = run_cosimulation(fmus, scenario_config(sc), mode="ideal", seed=1, steps=400)
    ref = run_monolithic(changed, 0.02, "ideal", 1, 400)
    np.testing.assert_allclose(res.traces["u"], ref["u"], atol=1e-9)
    np.testing.assert_allclose(res.traces["x"][0], [1.0, -1.0])
    base = run_monolithic(paper.system, 0.02, "ideal", 1, 400)
    assert not np.allclose(base["u"], ref["u"])


@contextmanager
def _instance(fmus, key, tag):
    """A real instance of one FMU, terminated, freed and unzipped files removed after."""
    ex = Extracted({key: fmus[key]})
    inst = FmuInstance(key, fmus[key], ex.dirs[key], f"{key}_{tag}")
    try:
        yield inst
    finally:
        inst.close()
        ex.cleanup()


def test_impossible_design_is_an_error_status_with_a_message_and_the_host_goes_on(paper, fmus):
    cfg = scenario_config(paper)
    params = fmu_parameters("controller", cfg)
    # B1 = 0: (A, B1) is stabilizable (A = -I) but then make A unstable -> not stabilizable
    for k in list(params):
        if k.startswith("B1["):
            params[k] = 0.0
    params["A[1,1]"] = 0.5
    with _instance(fmus, "controller", "bad") as inst:
        with pytest.raises(CosimError) as err:
            inst.initialize(params, T=1.0)
        msg = str(err.value)
        assert "not stabilizable" in msg and "0.5" in msg
        assert any(status in ("Error", "Fatal") for status, _ in inst.messages)
    gc.collect()
    # the process and fmpy still work: a normal run afterwards is correct
    res = run_cosimulation(fmus, cfg, mode="kalman", seed=0, steps=200)
    ref = run_monolithic(paper.system, paper.h, "kalman", 0, 200)
    np.testing.assert_allclose(res.traces["u"], ref["u"], atol=1e-9)


def test_bad_parameter_in_fmu_names_it(paper, fmus):
    cfg = scenario_config(paper)
    params = fmu_parameters("plant", cfg)
    params["V_y[1,2]"] = 0.5          # asymmetric covariance
    with _instance(fmus, "plant", "asym") as inst:
        with pytest.raises(CosimError, match=r"V_y is not symmetric"):
            inst.initialize(params, T=1.0)


def test_nan_input_is_refused_with_discard_and_a_message_then_recovers(paper, fmus):
    cfg = scenario_config(paper)
    with _instance(fmus, "controller", "nan") as inst:
        inst.initialize(fmu_parameters("controller", cfg), T=1.0)
        s = inst.slave
        s.setReal([inst.vr["xhat[2]"]], [float("nan")])
        status = inst.do_step(inst.component, 0.0, 0.01, 1)
        assert status == 2                                   # fmi2Discard
        assert any("xhat[2]" in m and "not finite" in m for _, m in inst.messages)
        s.setReal([inst.vr["xhat[2]"]], [0.25])             # a finite value: steps again
        assert inst.do_step(inst.component, 0.0, 0.01, 1) == 0
        u = s.getReal([inst.vr["u[1]"], inst.vr["u[2]"]])
        assert np.all(np.isfinite(u)) and np.any(np.abs(u) > 0)


def test_nan_input_stops_the_master_with_a_named_error(paper, fmus):
    """A NaN reaching the estimator makes the master stop, naming FMU and input."""
    cfg = scenario_config(paper)
    with _instance(fmus, "estimator", "nan2") as inst:
        inst.initialize(fmu_parameters("estimator", cfg), T=1.0)
        vr = (ctypes.c_uint * 1)(inst.vr["y[1]"])
        val = (ctypes.c_double * 1)(float("inf"))
        assert inst.set_real(inst.component, ctypes.addressof(vr), 1, ctypes.addressof(val)) == 0
        st = inst.do_step(inst.component, 0.0, 0.01, 1)
        assert st == 2
        err = inst.fail("fmi2DoStep at t = 0 s", st)
        assert "estimator FMU" in str(err) and "y[1] = inf" in str(err)


def test_wrong_communication_step_is_refused(paper, fmus):
    cfg = scenario_config(paper)
    with _instance(fmus, "plant", "step") as inst:
        inst.initialize(fmu_parameters("plant", cfg), T=1.0)
        assert inst.do_step(inst.component, 0.0, 0.05, 1) == 2
        assert any("differs from this FMU's sample period h = 0.01" in m for _, m in inst.messages)
        assert inst.do_step(inst.component, 0.0, 0.01, 1) == 0


def test_fixed_parameter_change_after_initialization_is_refused(paper, fmus):
    cfg = scenario_config(paper)
    with _instance(fmus, "controller", "fixed") as inst:
        inst.initialize(fmu_parameters("controller", cfg), T=1.0)
        inst.slave.setReal([inst.vr["Q[1,1]"]], [5.0])
        assert inst.slave.getReal([inst.vr["Q[1,1]"]]) == [1.0]
        assert any("Q[1,1] is fixed" in m for _, m in inst.messages)
