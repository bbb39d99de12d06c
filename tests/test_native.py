"""Native (C) FMUs of the design (orchestrator.cosim.native, orchestrator.interop.native):
the closed loop with native controller and estimator equals the all-pythonfmu loop, the
native plant's noise has the designed covariance and gives the predicted cost, and the
FMUs validate, round-trip their state, refuse bad parameters and load from awkward paths.
The native noise equals numpy's draws: tests/test_native_noise.py."""
from __future__ import annotations

import dataclasses
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

from orchestrator.cosim.master import run_system
from orchestrator.interop.native import native_system
from orchestrator.running import build, scenario_system
from orchestrator.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent

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


@pytest.mark.slow
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


@pytest.mark.parametrize("architecture, estimator, tracking", [
    ("distributed", "kalman", "regulator"), ("distributed", "ideal", "lq"),
    ("centralized", "ideal", "lq")])
@pytest.mark.slow
def test_per_vehicle_native_controllers_and_estimators_equal_the_pythonfmu_loop(
        tmp_path, architecture, estimator, tracking):
    """formation-4 per vehicle: one native FMU per kind, each vehicle's own values as
    parameters (offsets, slot weights, rows of the stacked gain), equal to the pythonfmu
    loop to 1e-12, for each estimator mode and both tracking laws."""
    sc = load_scenario("formation-4").with_run(
        T=20.0, deployment="per-vehicle", architecture=architecture, estimator=estimator,
        tracking=tracking)
    system, py, ns = _native(sc, tmp_path, ("vehicle_estimator", "vehicle_controller",
                                            "central_controller"))
    ref, _, _ = run_system(system, py, sc.steps)
    got, _, _ = run_system(ns.system, ns.fmus, sc.steps)
    _assert_equal_traces(ref, got)
    ctrl = [c for c in ns.system.components if c.name.startswith("controller_")]
    assert len(ctrl) == 4 and ctrl[0].parameters == {}       # the start values: vehicle 1
    assert all(c.parameters for c in ctrl[1:])                # the others' own values


@pytest.mark.slow
def test_a_remus_fleet_with_sensors_runs_every_fmu_native(tmp_path):
    """With navigation sensors every FMU has a native form: the nonlinear vehicle its own
    C model (sensors included, orchestrator.cosim.native_remus), the multi-rate estimator
    its own (orchestrator.cosim.native_multirate); with the native leader and controllers
    beside them the loop equals the pythonfmu one to 1e-12."""
    text = (ROOT / "orchestrator/scenario/builtin/formation-4.toml").read_text()
    text = text.replace('model = "remus100"', 'model = "remus100-6dof"')
    (tmp_path / "six.toml").write_text(text + '\n[sensors]\nkind = "remus"\n')
    sc = load_scenario(tmp_path / "six.toml").with_run(
        T=10.0, deployment="per-vehicle", architecture="distributed")
    system, py, ns = _native(sc, tmp_path)
    assert ns.fmus["remus6dof"].name == "AuvRemus6dofNative.fmu"
    assert ns.fmus["vehicle_estimator"].name == "AuvVehicleEstimatorNative.fmu"
    assert {"remus6dof", "vehicle_estimator"} <= ns.native_keys
    assert ns.fmus["vehicle_controller"].name == "AuvVehicleControllerNative.fmu"
    ref, _, _ = run_system(system, py, sc.steps)
    got, _, _ = run_system(ns.system, ns.fmus, sc.steps)
    _assert_equal_traces(ref, got)


def _with_plant_seed(system, seed):
    return dataclasses.replace(system, components=tuple(
        dataclasses.replace(c, parameters={**c.parameters, "seed": seed})
        if c.fmu == "plant" else c for c in system.components))


def test_the_native_plant_noise_has_the_designed_covariance(tmp_path):
    """The all-native loop; the plant draws numpy's normals in C (PCG64, ziggurat):
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
    """The paper's loop, every FMU native (the plant's noise drawn in C, seeded by the host
    through the plant's seed parameter): the cost rate over 8 seeds agrees with the Lyapunov prediction within 4 standard errors."""
    from controller_fmu.regulator import tracking_law
    from estimator_fmu.registry import make_estimator
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


@pytest.mark.slow
def test_native_fmus_validate_and_ship_their_sources(f4_native, tmp_path):
    """fmpy validates the native FMUs clean (the vehicle controller's 900 variables take
    fmpy's full validation 9 s: its XML is checked against the FMI schema instead);
    needsExecutionTool false; the sources are in sources/ and listed; the binary needs only
    libc and libm."""
    import subprocess

    from fmpy import read_model_description
    from fmpy.validation import validate_fmu
    _, ns = f4_native
    for key in ("leader", "vehicle", "vehicle_estimator", "vehicle_controller"):
        path = ns.fmus[key]
        if key != "vehicle_controller":
            assert validate_fmu(str(path)) == [], key
        md = read_model_description(str(path), validate=True)
        cs = md.coSimulation
        assert not cs.needsExecutionTool and cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
        with zipfile.ZipFile(path) as z:
            names = set(z.namelist())
            root = etree.fromstring(z.read("modelDescription.xml"))
            assert [f.get("name") for f in root.iterfind("CoSimulation/SourceFiles/File")] == [
                "fmu_core.c", "linear_fmu.c", "numpy_random.c"]
            assert {"sources/fmu_core.c", "sources/fmu_core.h", "sources/linear_fmu.c",
                    "sources/linear_model.h", "sources/numpy_random.c", "sources/numpy_random.h",
                    "sources/native_model.h", "sources/fmi2Functions.h",
                    f"binaries/linux64/{path.stem}.so"} <= names
            lib = tmp_path / f"{path.stem}.so"
            lib.write_bytes(z.read(f"binaries/linux64/{path.stem}.so"))
        needed = subprocess.run(["ldd", str(lib)], capture_output=True, text=True).stdout
        libs = {ln.split()[0] for ln in needed.splitlines() if "=>" in ln}
        assert libs <= {"libm.so.6", "libc.so.6"}, libs


@pytest.fixture(scope="module")
def f4_native(tmp_path_factory):
    """formation-4 distributed, every linear FMU native."""
    tmp = tmp_path_factory.mktemp("f4n")
    sc = load_scenario("formation-4").with_run(T=10.0, deployment="per-vehicle",
                                               architecture="distributed")
    return sc, _native(sc, tmp)[2]


def _instance(ns, key, folder, name="probe", **parameters):
    from fmpy import extract

    from orchestrator.cosim.instance import FmuInstance
    unzip = extract(str(ns.fmus[key]), unzipdir=str(folder))
    inst = FmuInstance(key, ns.fmus[key], unzip, name)
    inst.initialize(parameters, T=10.0)
    return inst


def _driver(inst, vin, vout, feed, h):
    """Steps k0..k1-1: set the inputs of row k, read every output, step; the outputs."""
    def drive(k0, k1):
        rows = []
        for k in range(k0, k1):
            inst.slave.setReal(vin, list(feed[k]))
            rows.append(inst.slave.getReal(vout))
            inst.slave.doStep(k * h, h)
        return np.array(rows)
    return drive


def test_native_state_round_trip_is_bit_identical(f4_native, tmp_path):
    """Get, set, serialize and deserialize the plant's and the controller's state half way:
    the second half replays bit for bit (the plant's noise generator included)."""
    sc, ns = f4_native
    for key, inputs in (("vehicle", ["u[1]", "u[2]", "u[3]"]),
                        ("vehicle_controller", ["xhat[1]", "xhat[4]", "z[1]", "nbr[1].eta[2]"])):
        inst = _instance(ns, key, tmp_path / key)
        outs = [v.name for v in inst.md.modelVariables if v.causality == "output"]
        vin, vout = list(inst.vrs(inputs)), list(inst.vrs(outs))
        rng = np.random.default_rng(1)
        feed = rng.standard_normal((200, len(inputs)))

        drive = _driver(inst, vin, vout, feed, sc.h)
        drive(0, 100)
        state = inst.slave.getFMUState()
        first = drive(100, 200)
        inst.slave.setFMUState(state)
        assert np.array_equal(drive(100, 200), first), key
        blob = inst.slave.serializeFMUState(state)
        inst.slave.setFMUState(inst.slave.deserializeFMUState(blob))
        assert np.array_equal(drive(100, 200), first), key
        assert np.std(first[:, 0]) > 0
        inst.slave.freeFMUState(state)
        inst.close()


@pytest.mark.parametrize("key, name, fragment", [
    ("vehicle_controller", "D[1,2]", "parameter D[1,2] = nan is not finite"),
    ("vehicle_estimator", "q0[3]", "parameter q0[3] = nan is not finite"),
    ("vehicle", "Ad[2,2]", "parameter Ad[2,2] = nan is not finite"),
])
def test_a_nan_gain_is_an_error_status_naming_the_variable(f4_native, tmp_path, key, name,
                                                           fragment):
    """fmi2ExitInitializationMode returns fmi2Error (not fatal, the host goes on) with a
    logged message naming the variable; a wrong step size is an error naming h."""
    from fmpy.fmi1 import FMICallException

    from orchestrator.cosim.instance import CosimError
    sc, ns = f4_native
    with pytest.raises(CosimError) as exc:
        _instance(ns, key, tmp_path / "bad", **{name: float("nan")})
    assert fragment in str(exc.value) and "status 3 (error)" in str(exc.value)
    inst = _instance(ns, key, tmp_path / "ok")
    with pytest.raises(FMICallException):
        inst.slave.doStep(0.0, 2 * sc.h)
    assert "this FMU is designed for h = 0.01 s" in inst.errors()
    inst.slave.doStep(0.0, sc.h)                       # the instance is still usable
    inst.close()


@pytest.mark.parametrize("folder", ["with space", "per%25cent%", "tést ñ"])
def test_native_fmus_load_from_awkward_resource_paths(f4_native, tmp_path, folder):
    """Unzipped under a folder with spaces, percent signs or non-ASCII letters (which crash
    a host with pythonfmu 0.7's FMUs), the native estimator instantiates and steps."""
    sc, ns = f4_native
    inst = _instance(ns, "vehicle_estimator", tmp_path / folder / "fmu")
    inst.slave.setReal(list(inst.vrs(["y[1]"])), [2.0])
    before = inst.slave.getReal(list(inst.vrs(["xhat[1]"])))[0]
    inst.slave.doStep(0.0, sc.h)
    assert before != 0.0
    inst.close()


@pytest.mark.slow
def test_libcosim_and_fmpy_run_the_native_export(tmp_path):
    """`auv-cosim export native`: libcosim runs the OSP system bit-identically to our
    Jacobi master on the same native FMUs; fmpy's simulate_ssp runs the SSP archive."""
    pytest.importorskip("libcosimpy")
    from orchestrator.interop import libcosim
    from orchestrator.interop.native import export_native
    from orchestrator.interop.ssp import fmpy_parameter_set
    libcosim.quiet_libcosim()
    sc = load_scenario("formation-4").with_run(T=5.0, deployment="per-vehicle",
                                               architecture="centralized")
    paths = export_native(sc, tmp_path / "x")
    assert {p.name for p in paths.values() if p.suffix == ".fmu"} == {
        "AuvLeaderNative.fmu", "AuvVehicleNative.fmu", "AuvVehicleEstimatorNative.fmu",
        "AuvCentralControllerNative.fmu",
        "AuvGuidanceNative.fmu", "AuvAutopilotNative.fmu"}  # beside it (docs/guidance.md)
    system = scenario_system(sc)
    ns = native_system(system, build(sc, tmp_path / "py"), tmp_path / "n2")
    steps = 300
    lc = libcosim.run_libcosim(paths["system"], ns.system, steps)
    ours, _, _ = run_system(ns.system, ns.fmus, steps, coupling="jacobi")
    assert set(lc["traces"]) == set(ours)
    for key, arr in lc["traces"].items():
        assert np.array_equal(arr, ours[key]), key
    from fmpy.ssp.simulation import simulate_ssp
    res = simulate_ssp(str(paths["ssp"]), stop_time=1.0, step_size=sc.h,
                       parameter_set=fmpy_parameter_set(paths["ssp"]))
    assert len(res) >= 100


def _ecos() -> str:
    """The ecos command-line engine the ecospy wheel ships (skip with what is missing)."""
    import os
    import subprocess
    ecospy = pytest.importorskip("ecospy", reason="ecospy is not installed (pip install "
                                                  "ecospy; the test extra has it)")
    exe = os.path.join(os.path.dirname(ecospy.__file__), "binaries", "ecos")
    if not os.access(exe, os.X_OK):                 # the wheel may not set the run bit
        os.chmod(exe, 0o755)
    r = subprocess.run([exe, "--version"], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"the ecos engine does not start ({r.stderr.strip()[:120]}); on Debian "
                    "it needs libtbb12 (apt install libtbb12)")
    return exe


def _ecos_csv(path):
    """ecos's CSV: a header split at ', ' (its names hold commas: Ks[1,2]), 6 decimals."""
    lines = path.read_text().splitlines()
    head = [h.strip() for h in lines[0].split(", ")]
    data = np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]])
    assert data.shape[1] == len(head)
    return {h: data[:, j] for j, h in enumerate(head)}


@pytest.mark.slow
def test_ecos_runs_the_native_ssp_with_no_python(tmp_path):
    """The ecos engine (C++) runs the native SSP archive in a process with no Python and no
    PYTHON* variables or LD_PRELOAD: the plant's outputs equal our Jacobi master's on the
    same FMUs to ecos's CSV precision (6 decimals), over 200 steps of the closed loop."""
    import subprocess

    from orchestrator.interop.native import export_native
    exe = _ecos()
    sc = load_scenario("paper").with_run(T=2.0)
    paths = export_native(sc, tmp_path / "x")
    ns = native_system(scenario_system(sc), build(sc, tmp_path / "py"), tmp_path / "n")
    run = tmp_path / "ecos"
    run.mkdir()
    r = subprocess.run([exe, "simulate", "--path", str(paths["ssp"]), "--stopTime", "2",
                        "--stepSize", str(sc.h), "--noParallel"], cwd=run,
                       env={"PATH": "/usr/bin:/bin"}, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr[-500:]
    got = _ecos_csv(next(run.glob("*.csv")))
    ours, _, _ = run_system(ns.system, ns.fmus, sc.steps, coupling="jacobi")
    assert got["time"].size == sc.steps
    for name, col in (("y", 0), ("y", 1), ("x", 0), ("x", 1), ("e", 0)):
        trace = got[f"plant::{name}[{col + 1}][REAL]"]
        assert np.abs(trace - ours[name][:, col]).max() <= 6e-7, (name, col)
    assert np.std(ours["y"][:, 0]) > 1.0              # a moving, noisy loop


def _c_host_run(exe, sysfile, steps, h, out, valgrind=False):
    import subprocess
    cmd = [str(exe), str(sysfile), str(steps), repr(h), str(out)]
    if valgrind:
        cmd = ["valgrind", "--leak-check=full", "--errors-for-leak-kinds=definite",
               "--error-exitcode=9", "-q", *cmd]
    return subprocess.run(cmd, capture_output=True, text=True, env={}, timeout=600)


@pytest.mark.slow
def test_the_c_host_runs_the_all_native_system_like_our_master(tmp_path):
    """orchestrator/interop/native_host/c_host.c (libc, libdl; no Python, an empty environment) runs formation-4
    per vehicle, every FMU native, unzipped under a folder with a space, a percent sign and
    non-ASCII letters: every recorded output equals our Jacobi master's bit for bit. A NaN
    gain is one line naming the instance and the call, exit status 1."""
    from orchestrator.benchmarks.native import c_host_binary, write_c_host_system
    sc = load_scenario("formation-4").with_run(T=3.0, deployment="per-vehicle",
                                               architecture="distributed")
    system, py, ns = _native(sc, tmp_path)
    exe = c_host_binary(tmp_path)
    from fmu_common.interface import element_names
    names = [(c.name, nm) for c in ns.system.components if c.fmu != "leader"
             for o in c.arrays("output") if o.name in ("y", "u", "xhat")
             for nm in element_names(o.name, o.shape)]
    root = tmp_path / "dir with space" / "50%25 tést"
    sysfile = write_c_host_system(ns.system, ns.fmus, root, record=names)
    r = _c_host_run(exe, sysfile, sc.steps, sc.h, tmp_path / "c.csv")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("us_per_step ")
    got = np.loadtxt(tmp_path / "c.csv", delimiter=",", skiprows=1)
    ours, _, _ = run_system(ns.system, ns.fmus, sc.steps, coupling="jacobi")
    assert got.shape == (sc.steps, len(names) + 1)
    for j, (comp, nm) in enumerate(names, start=1):
        arr, idx = nm.split("[")[0], int(nm.split("[")[1].rstrip("]")) - 1
        assert np.array_equal(got[:, j], ours[f"{comp}.{arr}"][:, idx]), (comp, nm)
    bad = sysfile.read_text() + "real controller_2 0 nan\n"
    (root / "bad.txt").write_text(bad)
    r = _c_host_run(exe, root / "bad.txt", 10, sc.h, tmp_path / "bad.csv")
    assert r.returncode == 1
    assert "c_host: controller_2 fmi2ExitInitializationMode failed at t = 0 (Error)" in r.stderr
    assert "parameter A_eta[1,1] = nan is not finite" in r.stderr


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
def test_the_native_fmus_load_run_and_unload_cleanly_under_valgrind(tmp_path):
    """The C host runs the paper's all-native loop under valgrind (memcheck, full leak
    check): no invalid access, no definitely lost block, after fmi2FreeInstance and
    dlclose."""
    from orchestrator.benchmarks.native import c_host_binary, write_c_host_system
    sc = load_scenario("paper").with_run(T=1.0)
    _, _, ns = _native(sc, tmp_path)
    exe = c_host_binary(tmp_path)
    sysfile = write_c_host_system(ns.system, ns.fmus, tmp_path / "u")
    r = _c_host_run(exe, sysfile, 100, sc.h, tmp_path / "v.csv", valgrind=True)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "Invalid" not in r.stderr and "definitely lost" not in r.stderr
    assert np.loadtxt(tmp_path / "v.csv", delimiter=",", skiprows=1).shape[0] == 100


def test_export_native_without_a_compiler_is_one_line_and_creates_nothing(tmp_path):
    import os
    import subprocess
    import sys
    out = tmp_path / "never"
    env = dict(os.environ, CC=str(tmp_path / "no-such-cc"))
    r = subprocess.run([sys.executable, "-m", "orchestrator", "export", "native", "--scenario",
                        "paper", "--out", str(out)], capture_output=True, text=True, env=env,
                       timeout=120)
    assert r.returncode == 2 and not out.exists()
    assert r.stderr.strip().splitlines() == [
        f"auv-cosim export: error: no C compiler: '{tmp_path / 'no-such-cc'}' is not on PATH "
        "(install gcc, or set CC)"]


@pytest.mark.parametrize("cc, expected", [
    ("false", "the C compiler {path} failed (exit status 1) and printed nothing"),
    ("script", "the C compiler {path} failed (exit status 1): cc1: fatal error: no space left"),
])
def test_a_failing_compiler_is_one_line_naming_it_and_what_failed(tmp_path, cc, expected):
    """CC=false (or a compiler that fails with a message): one line naming the FMU being
    built, the compiler, its exit status and its first error line (or that it printed
    nothing), exit status 2; no FMU written."""
    import os
    import subprocess
    import sys
    path = shutil.which("false") if cc == "false" else str(tmp_path / "cc")
    if cc == "script":
        Path(path).write_text('#!/bin/sh\necho "cc1: fatal error: no space left" >&2\n'
                              'echo "compilation terminated." >&2\nexit 1\n')
        os.chmod(path, 0o755)
    out = tmp_path / "x"
    env = dict(os.environ, CC=path, AUV_COSIM_CACHE=str(tmp_path / "cache"))
    r = subprocess.run([sys.executable, "-m", "orchestrator", "export", "native", "--scenario",
                        "paper", "--out", str(out)], capture_output=True, text=True, env=env,
                       timeout=300)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        "auv-cosim export: error: building AuvPlantNative: " + expected.format(path=path)]
    assert not list(out.rglob("*.fmu"))
