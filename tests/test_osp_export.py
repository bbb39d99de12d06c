"""OSP export: connection checks, schema-valid XML, libcosim against our Jacobi master.

libcosim (Open Simulation Platform) runs the exported system through libcosimpy; its
fixed-step algorithm lets every FMU see the other FMUs' outputs of the previous
communication point, which ``run_cosimulation(..., coupling="jacobi")`` reproduces: the
traces must be bit-identical (tolerance 0).
"""
from __future__ import annotations

import numpy as np
import pytest
from lxml import etree

from estimator_fmu.estimators import ESTIMATOR_MODES, make_estimator
from controller_fmu.regulator import tracking_law
from orchestrator import osp_export
from orchestrator.fmu_build import FMU_KINDS, interface_of
from orchestrator.master import fmu_parameters, run_cosimulation
from orchestrator.osp_export import (OSP_MD_NS, OSP_SYSTEM_NS, SIMULATORS, Connection,
                                     ExportError, VariableInfo, check_connections,
                                     export_osp, jacobi_closed_loop, system_connections,
                                     validate_osp_file)
from orchestrator.scenario import load_scenario
from orchestrator.workflow import scenario_config
from fmu_common.interface import element_names
from plant_model.discretization import discretize
from plant_model.plant import NoiseStream

SYS = f"{{{OSP_SYSTEM_NS}}}"
MD = f"{{{OSP_MD_NS}}}"


@pytest.fixture(scope="module")
def paper():
    return load_scenario("paper")


@pytest.fixture(scope="module")
def exported(paper, tmp_path_factory):
    return export_osp(paper, tmp_path_factory.mktemp("osp_paper"))


def _planned(sc) -> dict[str, dict[str, VariableInfo]]:
    cfg = scenario_config(sc)
    return {key: {name: VariableInfo(spec.causality, spec.type)
                  for spec in interface_of(FMU_KINDS[key], cfg)
                  for name in element_names(spec.name, spec.shape)}
            for key in SIMULATORS}


# ------------------------------------------------------------------ connection checks

def test_the_paper_loop_connects(paper):
    conns = system_connections(paper.system.dims)
    check_connections(_planned(paper), conns)
    d = paper.system.dims
    assert len(conns) == 2 * d["p"] + 2 * (d["n"] + d["r"] + d["l"]) + 2 * d["m"]
    assert Connection(("controller", "u[2]"), ("estimator", "u[2]")) in conns


def _refused(variables, conns, *fragments):
    with pytest.raises(ExportError) as exc:
        check_connections(variables, conns)
    msg = str(exc.value)
    assert msg.startswith("export refused: "), msg
    for f in fragments:
        assert f in msg, msg
    return msg


def test_refuses_a_variable_the_fmu_lacks(paper):
    conns = system_connections(paper.system.dims) + [
        Connection(("plant", "y[3]"), ("estimator", "y[3]"))]
    _refused(_planned(paper), conns, "'plant' has no variable 'y[3]'")
    conns = system_connections(paper.system.dims)
    conns[0] = Connection(("plant", "y[1]"), ("estimator", "yy[1]"))
    _refused(_planned(paper), conns, "'estimator' has no variable 'yy[1]'")


def test_refuses_an_unknown_simulator(paper):
    conns = system_connections(paper.system.dims) + [
        Connection(("plant", "e[1]"), ("logger", "e[1]"))]
    _refused(_planned(paper), conns, "no simulator 'logger'")


def test_refuses_two_outputs(paper):
    conns = system_connections(paper.system.dims) + [
        Connection(("plant", "e[1]"), ("controller", "u[1]"))]
    _refused(_planned(paper), conns, "connects two outputs", "plant.e[1]", "controller.u[1]")


def test_refuses_two_inputs(paper):
    conns = system_connections(paper.system.dims) + [
        Connection(("plant", "u[1]"), ("estimator", "u[1]"))]
    _refused(_planned(paper), conns, "connects two inputs", "plant.u[1]", "estimator.u[1]")


def test_refuses_an_unconnected_input(paper):
    conns = [c for c in system_connections(paper.system.dims)
             if c.target != ("controller", "zhat[2]")]
    _refused(_planned(paper), conns, "input controller.zhat[2] is not connected")
    # the truth inputs of the estimator must be connected too (read only in 'ideal')
    conns = [c for c in system_connections(paper.system.dims) if c.target != ("estimator", "w[1]")]
    _refused(_planned(paper), conns, "input estimator.w[1] is not connected")


def test_refuses_an_input_fed_twice(paper):
    conns = system_connections(paper.system.dims) + [
        Connection(("plant", "e[1]"), ("controller", "xhat[1]"))]
    _refused(_planned(paper), conns, "input controller.xhat[1] is fed twice")


def test_refuses_a_parameter_or_type_mismatch():
    variables = {"a": {"out": VariableInfo("output", "Real"), "k": VariableInfo("parameter", "Real"),
                       "n": VariableInfo("output", "Integer")},
                 "b": {"in": VariableInfo("input", "Real")}}
    _refused(variables, [Connection(("a", "out"), ("a", "k"))],
             "target a.k is a parameter, not an input")
    _refused(variables, [Connection(("a", "k"), ("b", "in"))],
             "source a.k is a parameter, not an output")
    _refused(variables, [Connection(("a", "n"), ("b", "in"))],
             "connects a Integer output to a Real input")
    check_connections(variables, [Connection(("a", "out"), ("b", "in"))])


def test_export_refuses_before_building_or_writing(paper, tmp_path, monkeypatch):
    good = osp_export.system_connections
    monkeypatch.setattr(osp_export, "system_connections",
                        lambda dims: [c for c in good(dims) if c.target != ("plant", "u[1]")])
    out = tmp_path / "refused"
    with pytest.raises(ExportError, match=r"export refused: input plant\.u\[1\] is not connected"):
        export_osp(paper, out)
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
    assert [s.get("name") for s in sims] == list(SIMULATORS)
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
    assert pairs == [(c.source, c.target) for c in system_connections(paper.system.dims)]


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
    fmus = {k: exported[k] for k in SIMULATORS}
    with pytest.raises(ValueError, match="coupling 'jacobian'"):
        run_cosimulation(fmus, scenario_config(paper), mode="kalman", seed=0, steps=5,
                         coupling="jacobian")


@pytest.mark.parametrize("mode", ESTIMATOR_MODES)
def test_jacobi_closed_loop_model_reproduces_the_jacobi_run(paper, exported, mode):
    """The matrices the Jacobi Lyapunov prediction uses give the co-simulated traces
    exactly (same noise rows as the plant FMU)."""
    steps = 600
    fmus = {k: exported[k] for k in SIMULATORS}
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
    osp_export.quiet_libcosim()
    return osp_export


def test_libcosim_runs_the_export_like_our_jacobi_master(paper, exported, libcosim):
    steps = 3000
    cfg = scenario_config(paper)
    lc = libcosim.run_libcosim(exported["system"], cfg, steps)
    fmus = {k: exported[k] for k in SIMULATORS}
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
    lc = libcosim.run_libcosim(tmp_path / "OspSystemStructure.xml", cfg, steps)
    fmus = {k: exported[k] for k in SIMULATORS}
    jac = run_cosimulation(fmus, cfg, mode="classical", seed=7, steps=steps, coupling="jacobi")
    for key, arr in lc["traces"].items():
        assert np.array_equal(arr, jac.traces[key]), key


def test_libcosim_runs_a_fleet_export_like_our_jacobi_master(libcosim, tmp_path):
    sc = load_scenario("formation-4")
    paths = export_osp(sc, tmp_path)
    steps = 1000
    cfg = scenario_config(sc)
    lc = libcosim.run_libcosim(paths["system"], cfg, steps)
    jac = run_cosimulation({k: paths[k] for k in SIMULATORS}, cfg, mode=sc.estimator,
                           seed=sc.seed, steps=steps, tracking=sc.tracking, coupling="jacobi")
    for key, arr in lc["traces"].items():
        assert np.array_equal(arr, jac.traces[key]), key


def test_benchmark_libcosim_reports_both_and_checks_agreement(paper, libcosim):
    from orchestrator.bench import benchmark_libcosim
    r = benchmark_libcosim(paper, 300, repeats=1)
    for key in ("ours_gauss_seidel_us_per_step", "ours_jacobi_us_per_step",
                "libcosim_us_per_step", "speedup_gauss_seidel_vs_libcosim"):
        assert r[key] > 0, key
    assert r["libcosim_vs_jacobi_bit_identical"] is True
    assert r["libcosim_vs_jacobi_max_abs"] == 0.0
    assert r["versions"]["libcosimpy"] != "not installed"
