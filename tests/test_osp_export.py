"""OSP export: connection checks, schema-valid XML, libcosim against our Jacobi master.

libcosim (Open Simulation Platform) runs the exported system through libcosimpy; its
fixed-step algorithm lets every FMU see the other FMUs' outputs of the previous
communication point, which ``run_cosimulation(..., coupling="jacobi")`` reproduces: the
traces must be bit-identical (tolerance 0).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from lxml import etree

from controller_fmu.regulator import tracking_law
from estimator_fmu.registry import ESTIMATOR_MODES, estimator_kind, make_estimator
from orchestrator.analysis.jacobi import jacobi_closed_loop
from orchestrator.cosim.build import FMU_KINDS, interface_of
from orchestrator.interop.common import ExportError
from orchestrator.interop.osp import OSP_MD_NS, OSP_SYSTEM_NS, export_osp, validate_osp_file
from orchestrator.running import scenario_config, scenario_system
from orchestrator.scenario import load_scenario
from plant_model.discretization import discretize
from plant_model.plant import NoiseStream
from support.loop import fmu_parameters, run_cosimulation

SYS = f"{{{OSP_SYSTEM_NS}}}"
COMPONENTS = ("plant", "estimator", "controller")
MD = f"{{{OSP_MD_NS}}}"


@pytest.fixture(scope="module")
def exported(paper, tmp_path_factory):
    return export_osp(paper, tmp_path_factory.mktemp("osp_paper"))


def test_export_refuses_before_building_or_writing(paper, tmp_path):
    system = scenario_system(paper)
    cut = replace(system, connections=tuple(
        c for c in system.connections if (c.target, c.input) != ("plant", "u")))
    out = tmp_path / "refused"
    with pytest.raises(ExportError, match=r"export refused: input plant\.u\[1\] is not connected; "
                                          r"input plant\.u\[2\] is not connected"):
        export_osp(paper, out, system=cut)
    assert not out.exists() or not any(out.iterdir())


# ------------------------------------------------------------------------ the files

def test_paper_export_is_schema_valid_and_complete(paper, exported):
    for key in ("system", "plant_osp", "estimator_osp", "controller_osp"):
        assert validate_osp_file(exported[key]) == [], key
    root = etree.parse(str(exported["system"])).getroot()
    assert root.tag == SYS + "OspSystemStructure"
    assert float(root.find(SYS + "BaseStepSize").text) == paper.h
    assert float(root.find(SYS + "EndTime").text) == paper.T
    assert root.find(SYS + "Algorithm").text == "fixedStep"
    cfg = scenario_config(paper)
    sims = root.find(SYS + "Simulators").findall(SYS + "Simulator")
    assert [s.get("name") for s in sims] == list(COMPONENTS)
    assert [s.get("name") for s in sims] == scenario_system(paper).names
    for sim in sims:
        key = sim.get("name")
        assert (exported["system"].parent / sim.get("source")) == exported[key]
        written = {}
        for iv in sim.find(SYS + "InitialValues"):
            (typed,) = list(iv)
            written[iv.get("variable")] = (etree.QName(typed).localname, typed.get("value"))
        expected = fmu_parameters(key, cfg)
        assert set(written) == set(expected), key
        for name, value in expected.items():
            kind, text = written[name]
            if kind == "Real":
                assert float(text) == float(value), name          # repr: exact round trip
            elif kind == "Integer":
                assert int(text) == int(value), name
            else:
                assert kind == "String" and text == str(value), name
    kinds = {(s.get("name"), iv.get("variable")): etree.QName(iv[0]).localname
             for s in sims for iv in s.find(SYS + "InitialValues")}
    assert kinds[("plant", "seed")] == "Integer"
    assert kinds[("plant", "noise_convention")] == "String"
    assert kinds[("estimator", "mode")] == "String"
    assert kinds[("controller", "tracking")] == "String"
    conns = root.find(SYS + "Connections").findall(SYS + "VariableConnection")
    pairs = [tuple((v.get("simulator"), v.get("name")) for v in c) for c in conns]
    assert pairs == [(c.source, c.target) for c in scenario_system(paper).scalar_connections()]


def test_model_descriptions_declare_groups_and_units(paper, exported):
    root = etree.parse(str(exported["plant_osp"])).getroot()
    assert root.tag == MD + "OspModelDescription"
    units = {u.get("name"): dict(u[0].attrib) for u in root.find(MD + "UnitDefinitions")}
    assert units == {"s": {"s": "1"}}                       # h; the paper's example is unitless
    groups = {g.get("name"): g for g in root.find(MD + "VariableGroups")}
    cfg = scenario_config(paper)
    assert set(groups) == {s.name for s in interface_of(FMU_KINDS["plant"], cfg)}
    assert [v.get("ref") for v in groups["y"]] == ["y[1]", "y[2]"]
    assert groups["h"][0].get("unit") == "s"


def test_schema_validation_catches_what_osp_refuses(exported, tmp_path):
    doc = etree.parse(str(exported["system"]))
    doc.getroot().find(SYS + "BaseStepSize").text = "a hundredth"
    bad = tmp_path / "OspSystemStructure.xml"
    doc.write(str(bad))
    assert any("BaseStepSize" in p for p in validate_osp_file(bad))
    md = etree.parse(str(exported["controller_osp"]))
    groups = md.getroot().find(MD + "VariableGroups")
    force = etree.SubElement(groups, MD + "Force", name="too_many")
    for i in range(4):                                     # OSP-IS: a Force has at most 3
        etree.SubElement(force, MD + "Variable", ref=f"u[{i % 2 + 1}]")
    bad_md = tmp_path / "AuvController_OspModelDescription.xml"
    md.write(str(bad_md))
    assert validate_osp_file(bad_md)


@pytest.mark.slow
def test_fleet_export_uses_osp_typed_groups(tmp_path):
    sc = load_scenario("formation-4")
    paths = export_osp(sc, tmp_path)
    for key in ("system", "plant_osp", "estimator_osp", "controller_osp"):
        assert validate_osp_file(paths[key]) == [], key
    root = etree.parse(str(paths["plant_osp"])).getroot()
    units = {u.get("name"): dict(u[0].attrib) for u in root.find(MD + "UnitDefinitions")}
    assert units["N"] == {"kg": "1", "m": "1", "s": "-2"}
    assert units["m"] == {"m": "1"} and units["m/s"] == {"m": "1", "s": "-1"}
    groups = {g.get("name"): g for g in root.iter() if g.get("name") and g.tag != MD + "Unit"}
    force = groups["u.vehicle[2].force"]
    assert force.tag == MD + "Force"
    assert [(v.get("ref"), v.get("unit"), v.get("axis")) for v in force] == [
        ("u[4]", "N", "x"), ("u[5]", "N", "y"), ("u[6]", "N", "z")]
    pos = groups["x.vehicle[1].displacement"]
    assert pos.tag == MD + "LinearDisplacement"
    assert [v.get("ref") for v in pos] == ["x[1]", "x[2]", "x[3]"]
    assert all(v.get("unit") == "m" for v in pos)
    vel = groups["x.vehicle[1].velocity"]
    assert vel.tag == MD + "LinearVelocity" and [v.get("unit") for v in vel] == ["m/s"] * 3
    assert groups["w.vehicle[4].velocity"].tag == MD + "LinearVelocity"
    assert groups["y.vehicle[3].displacement"].tag == MD + "LinearDisplacement"
    assert groups["z"].tag == MD + "Generic"               # the leader's exosystem: no unit
    ctrl = etree.parse(str(paths["controller_osp"])).getroot()
    assert {g.tag for g in ctrl.iter(MD + "Force")} == {MD + "Force"}
    assert len(list(ctrl.iter(MD + "Force"))) == 4


# ------------------------------------------------------------- the Jacobi-coupled loop

def test_unknown_coupling_is_refused(paper, exported):
    fmus = {k: exported[k] for k in COMPONENTS}
    with pytest.raises(ValueError, match="coupling 'jacobian'"):
        run_cosimulation(fmus, scenario_config(paper), mode="kalman", seed=0, steps=5,
                         coupling="jacobian")


@pytest.mark.parametrize("mode", [k for k in ESTIMATOR_MODES
                                  if not estimator_kind(k).time_varying])
def test_jacobi_closed_loop_model_reproduces_the_jacobi_run(paper, exported, mode):
    """The matrices the Jacobi Lyapunov prediction uses give the co-simulated traces
    exactly (same noise rows as the plant FMU)."""
    steps = 600
    fmus = {k: exported[k] for k in COMPONENTS}
    res = run_cosimulation(fmus, scenario_config(paper), mode=mode, seed=3, steps=steps,
                           coupling="jacobi")
    model = discretize(paper.system, paper.h)
    est = make_estimator(paper.system, model, mode)
    Ks = tracking_law(paper.system, "lq").Ks
    Phi, Gam, Gx, _ = jacobi_closed_loop(model, est, Ks)
    ns = model.ns
    X = np.concatenate([paper.system.initial_state(), est.q0, est.Ce @ est.q0,
                        np.zeros(Ks.shape[0])])
    noise = NoiseStream.all_rows(model, 3, steps)
    e, u = np.zeros_like(res.traces["e"]), np.zeros_like(res.traces["u"])
    for k in range(steps):
        e[k], u[k] = model.E @ X[:ns], Gx @ X
        X = Phi @ X + Gam @ noise[k]
    scale = 1.0 + np.max(np.abs(res.traces["u"]))
    np.testing.assert_allclose(e, res.traces["e"], rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(u, res.traces["u"], rtol=0, atol=1e-9 * scale)


# --------------------------------------------------------------------------- libcosim

@pytest.fixture(scope="module")
def libcosim():
    pytest.importorskip("libcosimpy")
    from orchestrator.interop import libcosim as lc
    lc.quiet_libcosim()
    return lc


@pytest.mark.slow
def test_libcosim_runs_the_export_like_our_jacobi_master(paper, exported, libcosim):
    steps = 3000
    cfg = scenario_config(paper)
    lc = libcosim.run_libcosim(exported["system"], scenario_system(paper), steps)
    fmus = {k: exported[k] for k in COMPONENTS}
    jac = run_cosimulation(fmus, cfg, mode=paper.estimator, seed=paper.seed, steps=steps,
                           coupling="jacobi")
    gs = run_cosimulation(fmus, cfg, mode=paper.estimator, seed=paper.seed, steps=steps)
    assert set(lc["traces"]) == set(jac.traces)
    for key, arr in lc["traces"].items():
        assert arr.shape == jac.traces[key].shape, key
        assert np.array_equal(arr, jac.traces[key]), (key, np.max(np.abs(arr - jac.traces[key])))
    # the comparison can tell the couplings apart: Gauss-Seidel is another loop
    assert np.max(np.abs(lc["traces"]["u"] - gs.traces["u"])) > 0.1
    assert np.array_equal(lc["traces"]["ybar"], gs.traces["ybar"])   # same noise, no feedback


def test_libcosim_applies_integer_and_string_initial_values(paper, exported, libcosim, tmp_path):
    """Seed (Integer) and estimator mode (String) changed in OspSystemStructure.xml only."""
    import shutil
    for p in exported.values():
        shutil.copy2(p, tmp_path / p.name)
    doc = etree.parse(str(tmp_path / "OspSystemStructure.xml"))
    for iv in doc.getroot().iter(SYS + "InitialValue"):
        if iv.get("variable") == "seed":
            iv[0].set("value", "7")
        if iv.get("variable") == "mode":
            iv[0].set("value", "classical")
    doc.write(str(tmp_path / "OspSystemStructure.xml"))
    assert validate_osp_file(tmp_path / "OspSystemStructure.xml") == []
    steps = 500
    cfg = scenario_config(paper)
    lc = libcosim.run_libcosim(tmp_path / "OspSystemStructure.xml", scenario_system(paper), steps)
    fmus = {k: exported[k] for k in COMPONENTS}
    jac = run_cosimulation(fmus, cfg, mode="classical", seed=7, steps=steps, coupling="jacobi")
    for key, arr in lc["traces"].items():
        assert np.array_equal(arr, jac.traces[key]), key


def test_libcosim_runs_a_fleet_export_like_our_jacobi_master(libcosim, tmp_path):
    sc = load_scenario("formation-4")
    paths = export_osp(sc, tmp_path)
    steps = 1000
    cfg = scenario_config(sc)
    lc = libcosim.run_libcosim(paths["system"], scenario_system(sc), steps)
    jac = run_cosimulation({k: paths[k] for k in COMPONENTS}, cfg, mode=sc.estimator,
                           seed=sc.seed, steps=steps, tracking=sc.tracking, coupling="jacobi")
    for key, arr in lc["traces"].items():
        assert np.array_equal(arr, jac.traces[key]), key


@pytest.mark.slow
def test_benchmark_libcosim_reports_both_and_checks_agreement(paper, libcosim):
    from orchestrator.benchmarks.paper import benchmark_libcosim
    r = benchmark_libcosim(paper, 300, repeats=1)
    for key in ("ours_gauss_seidel_us_per_step", "ours_jacobi_us_per_step",
                "libcosim_us_per_step", "speedup_gauss_seidel_vs_libcosim"):
        assert r[key] > 0, key
    assert r["libcosim_vs_jacobi_bit_identical"] is True
    assert r["libcosim_vs_jacobi_max_abs"] == 0.0
    assert r["versions"]["libcosimpy"] != "not installed"


@pytest.mark.slow
@pytest.mark.parametrize("architecture", ["distributed", "centralized"])
def test_libcosim_runs_a_per_vehicle_export_like_our_jacobi_master(libcosim, tmp_path,
                                                                  architecture):
    """formation-4 per vehicle: 13 FMU instances of 4 FMUs, every vehicle's parameters in
    the system file; libcosim and our master with Jacobi coupling give the same traces."""
    from orchestrator.cosim.master import run_system
    sc = load_scenario("formation-4").with_run(deployment="per-vehicle",
                                                architecture=architecture)
    paths = export_osp(sc, tmp_path)
    system = scenario_system(sc)
    assert len(system.components) == 13
    steps = 500
    lc = libcosim.run_libcosim(paths["system"], system, steps)
    fmus = {c.fmu: paths[c.fmu] for c in system.components}
    traces, _, _ = run_system(system, fmus, steps, coupling="jacobi")
    assert set(lc["traces"]) == set(traces)
    for key, arr in lc["traces"].items():
        assert np.array_equal(arr, traces[key]), key
    # the vehicles differ (their own parameters reached libcosim): vehicle 1 is not vehicle 2
    assert not np.allclose(lc["traces"]["vehicle_1.x"], lc["traces"]["vehicle_2.x"])


def test_the_writers_take_a_system_and_its_fmus_not_a_scenario(tmp_path):
    """write_osp and write_ssp work from an ExportSet alone: the paper's system and FMUs,
    the signals unit-less (no scenario at hand), give schema-valid OSP files and an SSP
    archive whose system fmpy reads, with every component's FMU inside."""
    import zipfile
    from pathlib import Path

    from orchestrator.interop.export_set import ExportSet, SignalElement
    from orchestrator.interop.osp import write_osp
    from orchestrator.interop.ssp import write_ssp
    from orchestrator.running import build
    sc = load_scenario("paper")
    system = scenario_system(sc)
    fmus = build(sc, tmp_path)
    elements = {s.name: [SignalElement("", None, str(i + 1)) for i in range(s.size)]
                for c in system.components for s in c.interface
                if s.causality in ("input", "output")}
    export = ExportSet(system, fmus, {}, elements)
    paths = write_osp(export, tmp_path)
    assert all(validate_osp_file(p) == [] for k, p in paths.items()
               if k == "system" or k.endswith("_osp"))
    ssp = write_ssp(export, tmp_path / "paper.ssp")
    with zipfile.ZipFile(ssp) as z:
        names = set(z.namelist())
    assert "SystemStructure.ssd" in names
    assert {f"resources/{Path(p).stem}.fmu" for p in fmus.values()} <= names
