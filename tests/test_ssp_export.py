"""SSP export: the archive, the connection check, and the .ssp run by fmpy's simulate_ssp.

fmpy 0.3.x ``simulate_ssp`` couples the FMUs by a Jacobi scheme with outputs sampled
*after* the step: every connector starts at 0.0; in each step every component gets its
inputs from the connector values, steps, and its outputs are read; only then are the
connections applied. So each connection delays by one step, and an output that feeds
through (estimator, controller) is read after the step from the *new* internal state and
the *old* inputs. :func:`loop_reference` writes that loop out in numpy next to our
master's exact Gauss-Seidel loop; the same function with ``coupling='gauss-seidel'``
reproduces our orchestrator, with ``coupling='fmpy'`` reproduces simulate_ssp, both to
rounding. fmpy also ignores the archive's ParameterBindings unless they are passed as its
``parameter_set`` (``orchestrator.interop.ssp.fmpy_parameter_set``).
"""
from __future__ import annotations

import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

from controller_fmu.regulator import tracking_law
from estimator_fmu.registry import make_estimator
from orchestrator.cosim.system import Connection
from orchestrator.interop.common import ExportError
from orchestrator.interop.ssp import SSC_NS, SSD_NS, SSV_NS, export_ssp, fmpy_parameter_set
from orchestrator.running import scenario_config, scenario_system
from plant_model.discretization import discretize
from plant_model.plant import NoiseStream
from support.loop import fmu_parameters, run_cosimulation

fmpy_ssp = pytest.importorskip("fmpy.ssp.simulation")
from fmpy.ssp.ssd import read_ssd, read_ssv  # noqa: E402 - after the importorskip

NS = {"ssd": SSD_NS, "ssc": SSC_NS, "ssv": SSV_NS}
FMU_FILES = {"plant": "AuvPlant.fmu", "estimator": "AuvEstimator.fmu",
             "controller": "AuvController.fmu"}
#: signal -> component whose output it is
OWNER = {"y": "plant", "ybar": "plant", "x": "plant", "w": "plant", "z": "plant", "e": "plant",
         "xhat": "estimator", "what": "estimator", "zhat": "estimator", "u": "controller"}
STEPS = 300


# ------------------------------------------------------------------ reference loops
def loop_reference(system, h: float, mode: str, seed: int, steps: int, coupling: str,
                   tracking: str = "lq") -> dict[str, np.ndarray]:
    """Traces of the closed loop under a coupling scheme, as plain numpy.

    ``gauss-seidel`` (our master): row k = sample k; y[k] -> estimate[k] -> u[k] -> step.
    ``fmpy`` (simulate_ssp): row j = the outputs read after step j (sample j + 1 of the
    plant), every input set from the previous row (row -1 = all zeros).
    """
    model = discretize(system, h)
    est = make_estimator(system, model, mode)
    Ks = tracking_law(system, tracking).Ks
    Ad, Bd, M, E = model.Ad, model.Bd, model.M, model.E
    ns, p, m = model.ns, model.p, system.m
    nm = 2 * p + ns
    noise = NoiseStream.all_rows(model, seed, steps + 1)
    s, q = system.initial_state(), est.q0.copy()

    def plant_out(s, k):                       # [y, ybar, x, w, z, e] of sample k
        return np.concatenate([M @ s + noise[k, ns:], s, E @ s])

    def estimate(q, mvec):
        return est.Ce @ q + est.Dm @ mvec

    rows = np.zeros((steps, 3 * p + 2 * ns + m))
    if coupling == "gauss-seidel":
        for k in range(steps):
            po = plant_out(s, k)
            e_ = estimate(q, po[:nm])
            u = -Ks @ e_
            rows[k] = np.concatenate([po, e_, u])
            s = Ad @ s + Bd @ u + noise[k, :ns]
            q = est.Aq @ e_ + est.Bu @ u
    elif coupling == "fmpy":
        Vm, Ve, Vu = np.zeros(nm), np.zeros(ns), np.zeros(m)   # connector values
        for j in range(steps):
            # plant: u = Vu, step, read outputs of sample j + 1
            s = Ad @ s + Bd @ Vu + noise[j, :ns]
            po = plant_out(s, j + 1)
            # estimator: inputs Vm, Vu; doStep uses the estimate from its current q,
            # the output read after the step combines the new q with the old inputs
            q = est.Aq @ estimate(q, Vm) + est.Bu @ Vu
            eo = estimate(q, Vm)
            # controller: u from the estimate of the previous row
            uo = -Ks @ Ve
            Vm, Ve, Vu = po[:nm], eo, uo
            rows[j] = np.concatenate([po, eo, uo])
    else:
        raise ValueError(coupling)
    sizes = (("y", p), ("ybar", p), ("x", system.n), ("w", system.r), ("z", system.l),
             ("e", p), ("xhat", system.n), ("what", system.r), ("zhat", system.l), ("u", m))
    out, i = {}, 0
    for name, size in sizes:
        out[name] = rows[:, i:i + size]
        i += size
    return out


def fmpy_traces(result: np.ndarray, like: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """simulate_ssp's structured result as signal -> (rows, size) arrays."""
    return {k: np.column_stack([result[f"{OWNER[k]}.{k}[{i + 1}]"] for i in range(v.shape[1])])
            for k, v in like.items()}


def max_rel_error(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> float:
    return max(float(np.abs(a[k] - b[k]).max() / max(1.0, np.abs(b[k]).max())) for k in b)


# ------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def ssp_for(tmp_path_factory, paper):
    """estimator mode -> .ssp of the paper scenario built for that mode (cached)."""
    cache: dict[str, Path] = {}

    def get(mode: str) -> Path:
        if mode not in cache:
            d = tmp_path_factory.mktemp(f"ssp_{mode}")
            cache[mode] = export_ssp(paper.with_run(estimator=mode), d / f"paper_{mode}.ssp")
        return cache[mode]
    return get


@pytest.fixture(scope="module")
def paper_ssp(ssp_for):
    return ssp_for("kalman")


@pytest.fixture(scope="module")
def archive_fmus(paper_ssp, tmp_path_factory) -> dict[str, Path]:
    """The FMUs inside the archive, for our own master."""
    d = tmp_path_factory.mktemp("ssp_fmus")
    with zipfile.ZipFile(paper_ssp) as z:
        z.extractall(d)
    return {k: d / "resources" / f for k, f in FMU_FILES.items()}


def simulate(ssp: Path, h: float, steps: int, **kw) -> np.ndarray:
    return fmpy_ssp.simulate_ssp(str(ssp), stop_time=steps * h, step_size=h, **kw)


# ------------------------------------------------------------------ the archive
def test_archive_layout_and_schema(paper_ssp, paper):
    with zipfile.ZipFile(paper_ssp) as z:
        names = set(z.namelist())
        ssd = etree.fromstring(z.read("SystemStructure.ssd"))
    assert names == {"SystemStructure.ssd", "resources/AuvPlant.fmu", "resources/AuvEstimator.fmu",
                     "resources/AuvController.fmu", "resources/plant.ssv",
                     "resources/estimator.ssv", "resources/controller.ssv"}
    parsed = read_ssd(str(paper_ssp), validate=True)      # fmpy validates against the SSP 1.0 XSD
    assert ssd.tag == f"{{{SSD_NS}}}SystemStructureDescription" and ssd.get("version") == "1.0"
    assert [c.name for c in parsed.system.elements] == ["plant", "estimator", "controller"]
    assert [c.source for c in parsed.system.elements] == [
        f"resources/{f}" for f in FMU_FILES.values()]
    d = paper.system.dims
    n, m, r, p, l_ = d["n"], d["m"], d["r"], d["p"], d["l"]
    kinds = {c.name: [k.kind for k in c.connectors] for c in parsed.system.elements}
    assert kinds["plant"].count("input") == m
    assert kinds["plant"].count("output") == 3 * p + n + r + l_
    assert kinds["estimator"].count("input") == 2 * p + n + r + l_ + m
    assert kinds["estimator"].count("output") == n + r + l_
    assert kinds["controller"] == ["input"] * (n + r + l_) + ["output"] * m
    # every connector is typed
    for con in ssd.iterfind(".//ssd:Connector", NS):
        assert con.find("ssc:Real", NS) is not None, con.get("name")
    conns = {tuple(c.get(a) for a in ("startElement", "startConnector", "endElement", "endConnector"))
             for c in ssd.iterfind(".//ssd:Connection", NS)}
    assert len(conns) == (2 * p + n + r + l_) + (n + r + l_) + 2 * m
    assert ("plant", "y[1]", "estimator", "y[1]") in conns
    assert ("estimator", "zhat[2]", "controller", "zhat[2]") in conns
    assert ("controller", "u[2]", "plant", "u[2]") in conns
    assert ("controller", "u[1]", "estimator", "u[1]") in conns
    de = ssd.find("ssd:DefaultExperiment", NS)
    assert float(de.get("stopTime")) == paper.T
    assert float(de.find(".//FixedStepMaster").get("stepSize")) == paper.h


def test_parameter_sets_hold_the_scenario_values(paper_ssp, paper):
    cfg = scenario_config(paper)
    parsed = read_ssd(str(paper_ssp))
    for comp in parsed.system.elements:
        (binding,) = comp.parameterBindings
        assert binding.source == f"resources/{comp.name}.ssv"
        pset = read_ssv(str(paper_ssp), resource=binding.source, validate=True)
        got = {p.name: p for p in pset.parameters}
        want = fmu_parameters(comp.name, cfg)
        assert set(got) == set(want)
        for name, value in want.items():
            if got[name].type == "Real":
                assert float(got[name].value) == float(value), name      # repr round-trips
            elif got[name].type == "Integer":
                assert int(got[name].value) == int(value), name
            else:
                assert got[name].value == str(value), name
    assert [p.value for p in read_ssv(str(paper_ssp), resource="resources/estimator.ssv").parameters
            if p.name == "mode"] == ["kalman"]


# ------------------------------------------------------------------ wiring refused
def test_export_refuses_a_connection_to_a_missing_variable(paper, tmp_path):
    system = scenario_system(paper)
    bad = replace(system, connections=system.connections + (Connection("plant", "y", "controller", "y"),))
    with pytest.raises(ExportError,
                       match=r"controller \(AuvController\.fmu\) has no variable 'y\[1\]'"):
        export_ssp(paper, tmp_path / "bad.ssp", system=bad)
    assert not list(tmp_path.iterdir())                 # nothing written


# ------------------------------------------------------------------ runs
def test_gauss_seidel_reference_reproduces_our_orchestrator(archive_fmus, paper):
    """Checks the reference loop itself on the FMUs inside the archive."""
    res = run_cosimulation(archive_fmus, scenario_config(paper), mode="kalman", seed=0, steps=STEPS)
    ref = loop_reference(paper.system, paper.h, "kalman", 0, STEPS, "gauss-seidel")
    assert max_rel_error(res.traces, ref) < 1e-12


@pytest.mark.parametrize("mode", ["kalman", "ideal", "classical"])
def test_simulate_ssp_is_the_one_step_delayed_jacobi_loop(ssp_for, paper, mode):
    ssp = ssp_for(mode)
    result = simulate(ssp, paper.h, STEPS, parameter_set=fmpy_parameter_set(ssp))
    # t accumulates (t += h) and the loop runs while t < stop: 0.01 * 300 summed is just
    # below 3.0, so fmpy takes one step more than round(T / h)
    rows = len(result)
    assert rows in (STEPS, STEPS + 1)
    assert np.allclose(result["time"], np.cumsum(np.r_[0.0, np.full(rows - 1, paper.h)]))
    ref = loop_reference(paper.system, paper.h, mode, paper.seed, rows, "fmpy")
    assert max_rel_error(fmpy_traces(result, ref), ref) < 1e-12


def test_simulate_ssp_against_our_orchestrator(paper_ssp, archive_fmus, paper):
    """What agrees between fmpy's run and ours on the same seed, and what does not."""
    ours = run_cosimulation(archive_fmus, scenario_config(paper), mode="kalman", seed=0,
                            steps=STEPS).traces
    theirs = fmpy_traces(simulate(paper_ssp, paper.h, STEPS,
                                  parameter_set=fmpy_parameter_set(paper_ssp)), ours)
    # fmpy's row j holds sample j + 1; compare samples 1 .. STEPS - 1
    a = {k: v[:STEPS - 1] for k, v in theirs.items()}
    b = {k: v[1:STEPS] for k, v in ours.items()}
    C = paper.system.C
    # the uncontrolled parts (disturbance, leader, reference measurement) and the sensor
    # noise are the same numbers: same seed, same noise row per sample index
    for k in ("w", "z", "ybar"):
        assert np.abs(a[k] - b[k]).max() < 1e-12, k
    noise_a, noise_b = a["y"] - a["x"] @ C.T, b["y"] - b["x"] @ C.T
    assert np.abs(noise_a - noise_b).max() < 1e-12
    # the controlled loop is a different (delayed) discrete-time system: the vehicle
    # state and the control differ by the order of the signals themselves
    dx, du = np.abs(a["x"] - b["x"]).max(), np.abs(a["u"] - b["u"]).max()
    assert dx > 0.05 * np.abs(b["x"]).max() and du > 0.05 * np.abs(b["u"]).max()
    print(f"\nfmpy simulate_ssp vs our master, {STEPS} steps, seed 0: max |dx| = {dx:.3g} "
          f"(max |x| {np.abs(b['x']).max():.3g}), max |du| = {du:.3g} "
          f"(max |u| {np.abs(b['u']).max():.3g})")


# ------------------------------------------------------------------ parameters
def _with_parameter(ssp: Path, dst: Path, component: str, name: str, typ: str, value: str) -> Path:
    """A copy of the archive whose ``<component>.ssv`` sets ``name`` to ``value``."""
    target = f"resources/{component}.ssv"
    with zipfile.ZipFile(ssp) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == target:
                root = etree.fromstring(data)
                (param,) = [q for q in root.iterfind(".//ssv:Parameter", NS)
                            if q.get("name") == name]
                param.replace(param[0], etree.Element(f"{{{SSV_NS}}}{typ}", value=value))
                data = etree.tostring(root, xml_declaration=True, encoding="UTF-8")
            zout.writestr(item, data)
    return dst


def test_fmpy_ignores_bindings_unless_passed(paper_ssp, paper, tmp_path):
    ssp7 = _with_parameter(paper_ssp, tmp_path / "seed7.ssp", "plant", "seed", "Integer", "7")
    steps = 50
    ignored = simulate(ssp7, paper.h, steps)                       # fmpy's default
    applied = simulate(ssp7, paper.h, steps, parameter_set=fmpy_parameter_set(ssp7))
    rows = len(applied)
    ref0 = loop_reference(paper.system, paper.h, "kalman", 0, rows, "fmpy")
    ref7 = loop_reference(paper.system, paper.h, "kalman", 7, rows, "fmpy")
    assert max_rel_error(fmpy_traces(ignored, ref0), ref0) < 1e-12       # FMU start value seed 0
    assert max_rel_error(fmpy_traces(applied, ref7), ref7) < 1e-12       # the bound seed 7


def test_string_parameters_fmpy_cannot_set_are_checked(paper_ssp, tmp_path):
    ps = fmpy_parameter_set(paper_ssp)
    names = {p.name for p in ps.parameters}
    assert "plant.seed" in names and "estimator.h" in names and "controller.Q[1,1]" in names
    assert not {"plant.noise_convention", "estimator.mode", "controller.tracking"} & names
    bad = _with_parameter(paper_ssp, tmp_path / "ideal.ssp", "estimator", "mode", "String", "ideal")
    with pytest.raises(ExportError, match=r"estimator\.mode = 'ideal' is a String.*'kalman'"):
        fmpy_parameter_set(bad)
    assert len(fmpy_parameter_set(bad, strings="drop").parameters) == len(ps.parameters)




@pytest.mark.slow
def test_a_per_vehicle_archive_runs_in_fmpy_with_each_vehicles_values(tmp_path):
    """formation-4 per vehicle as SSP: fmpy's simulate_ssp runs the 13 components with each
    vehicle's parameter set; the uncontrolled parts (each vehicle's current, its sensor noise)
    are the numbers of our run, one sample later (fmpy's row j holds sample j + 1)."""
    from orchestrator.cosim.master import run_system
    from orchestrator.scenario import load_scenario
    sc = load_scenario("formation-4").with_run(deployment="per-vehicle",
                                                architecture="distributed")
    ssp = export_ssp(sc, tmp_path / "f4.ssp")
    with zipfile.ZipFile(ssp) as z:
        names = set(z.namelist())
    assert {f"resources/vehicle_{i}.ssv" for i in range(1, 5)} <= names
    assert "resources/AuvVehicleController.fmu" in names
    steps = 200
    result = simulate(ssp, sc.h, steps, parameter_set=fmpy_parameter_set(ssp))
    system = scenario_system(sc)
    from orchestrator.running import build
    fmus = build(sc, tmp_path / "fmus")
    ours, _, _ = run_system(system, fmus, steps)
    C = sc.fleet.views[0].C
    for i in range(1, 5):
        w = np.column_stack([result[f"vehicle_{i}.w[{k}]"] for k in range(1, 4)])[:steps - 1]
        assert np.abs(w - ours[f"vehicle_{i}.w"][1:steps]).max() < 1e-12, i
        x = np.column_stack([result[f"vehicle_{i}.x[{k}]"] for k in range(1, 7)])[:steps - 1]
        y = np.column_stack([result[f"vehicle_{i}.y[{k}]"] for k in range(1, 4)])[:steps - 1]
        noise = y - x @ C.T
        ours_noise = ours[f"vehicle_{i}.y"][1:steps] - ours[f"vehicle_{i}.x"][1:steps] @ C.T
        assert np.abs(noise - ours_noise).max() < 1e-12, i
    # and the vehicles' currents are their own (different streams)
    assert not np.allclose(ours["vehicle_1.w"], ours["vehicle_2.w"])
