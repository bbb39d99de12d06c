"""The built FMUs: fmpy validate clean, complete model descriptions, honest structure."""
from __future__ import annotations

import zipfile

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from orchestrator.cosim.build import FMU_KINDS, STACKED_KINDS, fmu_config
from orchestrator.running import scenario_config
from orchestrator.scenario import load_scenario


@pytest.fixture(scope="module")
def fmus(paper_fmus):
    return paper_fmus


@pytest.mark.parametrize("name", STACKED_KINDS)
def test_fmpy_validate_reports_no_problem(fmus, name):
    assert validate_fmu(str(fmus[name])) == []


@pytest.mark.parametrize("name", STACKED_KINDS)
def test_every_variable_has_a_description_and_structured_name(fmus, name):
    md = read_model_description(str(fmus[name]))
    assert md.variableNamingConvention == "structured"
    for v in md.modelVariables:
        assert v.description, v.name
    names = {v.name for v in md.modelVariables}
    assert {"A[1,1]", "A[2,2]", "B1[1,2]", "F[2,1]"} <= names


def test_sample_period_has_unit_seconds_and_default_experiment(fmus):
    md = read_model_description(str(fmus["plant"]))
    h = next(v for v in md.modelVariables if v.name == "h")
    assert h.unit == "s" and float(h.start) == 0.01
    assert md.defaultExperiment.stepSize == "0.01" or float(md.defaultExperiment.stepSize) == 0.01
    assert float(md.defaultExperiment.stopTime) == 300.0
    assert md.coSimulation.canHandleVariableCommunicationStepSize is False


def _deps(md, output):
    u = next(o for o in md.outputs if o.variable.name == output)
    return sorted(d.name for d in (u.dependencies or []))


def test_model_structure_declares_direct_feedthrough(fmus):
    plant = read_model_description(str(fmus["plant"]))
    est = read_model_description(str(fmus["estimator"]))
    ctrl = read_model_description(str(fmus["controller"]))
    # the sampled plant is strictly proper: y does not depend on u
    assert _deps(plant, "y[1]") == []
    # the estimate of sample k includes y[k] (current estimator), not u[k]
    d = _deps(est, "xhat[1]")
    assert "y[1]" in d and "ybar[2]" in d and not any(n.startswith("u[") for n in d)
    assert _deps(ctrl, "u[1]") == sorted(["xhat[1]", "xhat[2]", "what[1]", "what[2]",
                                           "zhat[1]", "zhat[2]"])
    for md in (plant, est, ctrl):
        outs = {v.name for v in md.modelVariables if v.causality == "output"}
        assert {u.variable.name for u in md.initialUnknowns} == outs


def test_start_values_come_from_the_scenario(tmp_path):
    sc = load_scenario("paper")
    changed = sc.system.with_changes(x0=[1.5, -2.0])
    cfg = fmu_config(changed.to_mapping(), changed.dims, 0.02, 10.0, 7, "classical")
    from orchestrator.cosim.build import build_fmus
    paths = build_fmus(cfg, tmp_path)
    md = read_model_description(str(paths["plant"]))
    starts = {v.name: v.start for v in md.modelVariables}
    assert float(starts["x0[1]"]) == 1.5 and float(starts["x0[2]"]) == -2.0
    assert float(starts["h"]) == 0.02 and int(starts["seed"]) == 7
    est = {v.name: v.start for v in read_model_description(str(paths["estimator"])).modelVariables}
    assert est["mode"] == "classical"


def test_fmu_ships_sources_only_and_unique_slave_modules(fmus):
    modules = set()
    for name, path in fmus.items():
        with zipfile.ZipFile(path) as z:
            files = z.namelist()
            slave = z.read("resources/slavemodule.txt").decode().strip()
        modules.add(slave)
        assert not any("__pycache__" in f or f.endswith(".pyc") for f in files)
        # a slave script lives only once, at the root of resources/
        assert sum(f.endswith(f"/{slave}.py") for f in files) == 1
        assert "binaries/linux64/" + FMU_KINDS[name].model + ".so" in files
    assert len(modules) == 3


def test_build_is_fast_and_config_matches(fmus):
    cfg = scenario_config(load_scenario("paper"))
    with zipfile.ZipFile(fmus["controller"]) as z:
        import json
        shipped = json.loads(z.read("resources/auv_controller_config.json"))
    assert shipped["dims"] == cfg["dims"] and shipped["system"]["B1"] == cfg["system"]["B1"]


# ------------------------------------------------------------------------- the FMU cache
def test_identical_builds_come_from_the_cache(fmu_cache, tmp_path):
    from orchestrator.cosim.build import build_fmus, build_key
    cfg = scenario_config(load_scenario("paper").with_run(seed=123))
    first = build_fmus(cfg, tmp_path / "a")
    entries = {p.name: p.stat().st_mtime_ns for p in fmu_cache.glob("*.fmu")}
    second = build_fmus(cfg, tmp_path / "b")
    # nothing rebuilt (other xdist workers may add their own entries meanwhile)
    assert {n: (fmu_cache / n).stat().st_mtime_ns for n in entries} == entries
    for k in STACKED_KINDS:
        assert first[k].read_bytes() == second[k].read_bytes()          # same build, same GUID
        assert first[k].name == f"{FMU_KINDS[k].model}.fmu"
    other = dict(cfg, h=0.02)
    assert build_key(FMU_KINDS["plant"], other) != build_key(FMU_KINDS["plant"], cfg)
    third = build_fmus(other, tmp_path / "c")
    assert read_model_description(str(third["plant"])).defaultExperiment.stepSize == "0.02"
    for k in STACKED_KINDS:                                          # three new entries
        name = f"{FMU_KINDS[k].model}-{build_key(FMU_KINDS[k], other)[:32]}.fmu"
        assert name not in entries and (fmu_cache / name).exists()
    fresh = build_fmus(cfg, tmp_path / "d", cache=False)             # a new build: a new GUID
    assert read_model_description(str(fresh["plant"])).guid != \
        read_model_description(str(first["plant"])).guid


@pytest.mark.slow
def test_concurrent_builds_into_one_folder_leave_whole_fmus(tmp_path):
    """Two processes build different scenarios' FMUs into the same folder at once, with an
    empty cache each time: every FMU left there is a whole, valid FMU of one of them."""
    import os
    import subprocess
    import sys
    import zipfile
    code = ("import sys; from orchestrator.scenario import load_scenario; "
            "from orchestrator.running import build; "
            "build(load_scenario(sys.argv[1]), sys.argv[2])")
    for attempt in range(2):
        out = tmp_path / f"out{attempt}"
        env = dict(os.environ, AUV_COSIM_CACHE=str(tmp_path / f"cache{attempt}"))
        procs = [subprocess.Popen([sys.executable, "-c", code, name, str(out)], env=env,
                                  stderr=subprocess.PIPE, text=True)
                 for name in ("paper", "formation-4", "paper")]
        for p in procs:
            assert p.wait(timeout=300) == 0, p.stderr.read()
        # formation-4's REMUS 100s also get the guidance interface (docs/guidance.md)
        assert sorted(f.name for f in out.iterdir()) == [
            "AuvAutopilot.fmu", "AuvController.fmu", "AuvEstimator.fmu", "AuvGuidance.fmu",
            "AuvPlant.fmu"]
        for f in out.iterdir():
            with zipfile.ZipFile(f) as z:
                assert z.testzip() is None, f
            assert validate_fmu(str(f)) == [], f


@pytest.mark.parametrize("name", sorted(k for k, v in FMU_KINDS.items() if not v.external))
def test_slave_reads_the_configuration_file_the_build_ships(name):
    """Every FMU we build (a user's vehicle FMU is copied, not built)."""
    import importlib

    kind = FMU_KINDS[name]
    slave = getattr(importlib.import_module(kind.module), kind.model)
    assert slave.config_file == kind.config_file
    assert slave.author == "auv-cosim"
