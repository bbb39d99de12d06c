"""The native FMUs' binaries for other platforms (orchestrator.cosim.platforms): win64
(MinGW-w64) and aarch64-linux beside linux64, run for real. The C host of orchestrator/interop/native_host is
cross-compiled too and run under wine (win64) and qemu-aarch64 (aarch64-linux) on the
exported FMUs of the paper loop (plant, estimator, controller: the noise of numpy's
generator, exp and log1p in its ziggurat's wedges and tail) and of a guided REMUS 100
vehicle's guidance and autopilot (exp, expm1, atan2, sin, cos, fmod, sqrt), and every
recorded trace is compared with the linux64 host's:

- aarch64-linux: bit for bit (glibc's libm gives the same bits on both; its hypot did
  not, so the C models compute a horizontal speed as sqrt(x*x + y*y));
- win64: within 1e-12 of each trace's largest magnitude. The DLLs take exp, expm1, log1p,
  sin, cos, atan2 and log from MinGW-w64's static libm (x87 code), which differs from
  glibc's in the last bits (1-2 ulp; sin and cos more near their zeros): one tail draw of
  the noise or one course angle an ulp apart, carried on by the loop. Measured: 1.4e-14
  (paper, 300 s) and 1.1e-13 (guided). sqrt, fmod and + - * / are IEEE, the same
  everywhere; nothing of the math comes from msvcrt.dll, so wine and Windows agree.

A platform whose tools are missing skips, naming the programs and Debian packages
(``.ci/run`` installs them). The platform choice itself (which platforms, the one-line
notes and errors of ``auv-cosim export native --platforms``) is tested without compiling.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from orchestrator.cosim.platforms import PLATFORMS, platform_compiler, resolve_platforms
from tests.support.cross_hosts import (
    CrossHost,
    build_host,
    host_system,
    missing_tools,
    stop_wine,
)

CROSS = ("win64", "aarch64-linux")
#: per platform: how far a trace may be from linux64's, relative to its largest magnitude
#: (0: bit for bit); see the module docstring
BOUND = {"aarch64-linux": 0.0, "win64": 1e-12}
ALL = ("linux64", *CROSS)
GUIDED_STEPS, GUIDED_H = 450, 0.05


# ------------------------------------------------------------------ the platform choice
def test_an_unknown_or_a_missing_platform_is_one_line_naming_it(monkeypatch):
    with pytest.raises(ValueError, match=r"^unknown platform\(s\) 'win32' \(known: linux64, "
                                         r"win64, aarch64-linux\)$"):
        resolve_platforms(["linux64", "win32"])
    monkeypatch.setenv("CC_WIN64", "/nonexistent/x86_64-w64-mingw32-gcc")
    with pytest.raises(ValueError) as exc:
        resolve_platforms(["win64"])
    assert str(exc.value) == ("win64: no cross compiler: '/nonexistent/x86_64-w64-mingw32-gcc'"
                              " is not on PATH (install Debian's gcc-mingw-w64-x86-64, or set"
                              " CC_WIN64)")
    found, notes = resolve_platforms(None)          # by default: a note, not an error
    assert "win64" not in found and "linux64" in found
    assert notes == [str(exc.value) + ": its binary is not in the FMUs"]


def test_export_native_with_a_requested_platform_lacking_its_compiler_writes_nothing(
        tmp_path):
    out = tmp_path / "never"
    env = dict(os.environ, CC_AARCH64_LINUX=str(tmp_path / "no-such-gcc"))
    r = subprocess.run([sys.executable, "-m", "orchestrator", "export", "native", "--scenario",
                        "paper", "--platforms", "linux64,aarch64-linux", "--out", str(out)],
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 2 and not out.exists()
    assert r.stderr.strip().splitlines() == [
        f"auv-cosim export: error: aarch64-linux: no cross compiler: '{tmp_path}/no-such-gcc'"
        " is not on PATH (install Debian's gcc-aarch64-linux-gnu, or set CC_AARCH64_LINUX)"]


# ------------------------------------------------------------------ the hosts
def _need(*platforms: str) -> None:
    why = [m for m in map(missing_tools, platforms) if m]
    if why:
        pytest.skip("; ".join(why))


def _buildable() -> tuple[str, ...]:
    """linux64 and every other platform whose compiler is here (skip if none)."""
    found = ("linux64", *(p for p in CROSS if platform_compiler(p) is not None))
    if len(found) == 1:
        _need(*CROSS)
    return found


@pytest.fixture(scope="module")
def hosts(tmp_path_factory):
    """Platform -> the C host built for it (the ones whose tools are here); one wine
    prefix for the module, its first start timed, its wineserver ended afterwards."""
    root = tmp_path_factory.mktemp("hosts")
    built: dict[str, CrossHost] = {}
    for p in ALL:
        if missing_tools(p) is None:
            built[p] = build_host(p, root / p, wineprefix=root / "wineprefix")
    if "win64" in built:
        t0 = time.perf_counter()
        r = subprocess.run([*built["win64"].wrapper, str(built["win64"].exe)],
                           capture_output=True, text=True, env=built["win64"].env, timeout=300)
        assert r.returncode == 2 and "usage: c_host" in r.stderr, r.stderr[-1000:]
        print(f"wine prefix made and the host started in {time.perf_counter() - t0:.1f} s")
    yield built
    if "win64" in built:
        stop_wine(built["win64"])


def _run(host: CrossHost, sysfile: Path, steps: int, h: float, out: Path) -> np.ndarray:
    r = host.run(host_system(sysfile, host), steps, h, out)
    assert r.returncode == 0, f"{host.platform}: {r.stderr[-2000:]}"
    assert r.stdout.startswith("us_per_step ")
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    assert rows.shape[0] == steps
    return rows


def _compare(ref: np.ndarray, got: np.ndarray, platform: str, header: list[str]) -> None:
    """Every trace of ``got`` equals ``ref``'s: bit for bit, or within :data:`BOUND` of the
    trace's largest magnitude (NaN nowhere). Prints how many samples differ."""
    assert np.all(np.isfinite(ref)) and got.shape == ref.shape
    assert np.array_equal(got[:, 0], ref[:, 0])                    # the same times
    same = ref.view(np.uint64) == got.view(np.uint64)
    scale = np.maximum(np.abs(ref).max(axis=0), 1e-300)
    rel = np.abs(got - ref).max(axis=0) / scale
    print(f"{platform}: {int((~same).sum())} of {same.size} samples differ, at most "
          f"{float(np.abs(got - ref).max()):.3g} ({float(rel.max()):.3g} of the trace)")
    bad = [(header[j], float(rel[j])) for j in range(ref.shape[1])
           if not same[:, j].all() and rel[j] > BOUND[platform]]
    assert not bad, f"{platform}: {len(bad)} traces beyond {BOUND[platform]}: {bad[:5]}"


def _binaries(fmu: Path) -> dict[str, str]:
    with zipfile.ZipFile(fmu) as z:
        return {n.split("/")[1]: n.split("/")[2] for n in z.namelist()
                if n.startswith("binaries/")}


# ------------------------------------------------------------------ (a) the paper loop
@pytest.fixture(scope="module")
def paper_system(tmp_path_factory):
    """The paper loop's native FMUs for every platform, its host system file (every
    plant, estimator and controller output recorded), steps and h."""
    platforms = _buildable()
    from orchestrator.benchmarks.native import write_c_host_system
    from orchestrator.interop.native import native_system
    from orchestrator.running import build, scenario_system
    from orchestrator.scenario import load_scenario
    tmp = tmp_path_factory.mktemp("paper")
    sc = load_scenario("paper")                     # 300 s, 30,000 steps
    ns = native_system(scenario_system(sc), build(sc, tmp / "py"), tmp / "native",
                       platforms=platforms)
    sysfile = write_c_host_system(ns.system, ns.fmus, tmp / "unzipped")
    return ns, sysfile, sc.steps, sc.h


@pytest.mark.slow
def test_the_paper_fmus_carry_three_platforms_and_validate(paper_system, tmp_path):
    """Each exported FMU: sources, modelDescription and the three binaries; fmpy validates
    it; the DLL exports exactly the fmi2 functions and imports KERNEL32 and msvcrt only."""
    _need(*CROSS)
    ns, _, _, _ = paper_system
    for key in ns.native_keys:
        fmu = ns.fmus[key]
        model = read_model_description(str(fmu)).coSimulation.modelIdentifier
        assert _binaries(fmu) == {"linux64": f"{model}.so", "win64": f"{model}.dll",
                                  "aarch64-linux": f"{model}.so"}
        assert validate_fmu(str(fmu)) == []
        with zipfile.ZipFile(fmu) as z:
            dll = z.read(f"binaries/win64/{model}.dll")
            arm = z.read(f"binaries/aarch64-linux/{model}.so")
            assert any(n.startswith("sources/") for n in z.namelist())
        assert dll[:2] == b"MZ"                                      # a PE file
        assert arm[:4] == b"\x7fELF" and int.from_bytes(arm[18:20], "little") == 183  # aarch64
        exports, imports = _pe_table(dll, tmp_path / f"{model}.dll")
        assert exports == FMI2_FUNCTIONS                    # the fmi2 functions, nothing else
        assert imports == {"KERNEL32.dll", "msvcrt.dll"}    # no libgcc or other DLL needed


#: the functions an FMI 2.0 co-simulation FMU exports (fmi2Functions.h)
FMI2_FUNCTIONS = {f"fmi2{n}" for n in (
    "GetTypesPlatform GetVersion SetDebugLogging Instantiate FreeInstance SetupExperiment "
    "EnterInitializationMode ExitInitializationMode Terminate Reset GetReal GetInteger "
    "GetBoolean GetString SetReal SetInteger SetBoolean SetString GetFMUstate SetFMUstate "
    "FreeFMUstate SerializedFMUstateSize SerializeFMUstate DeSerializeFMUstate "
    "GetDirectionalDerivative SetRealInputDerivatives GetRealOutputDerivatives DoStep "
    "CancelStep GetStatus GetRealStatus GetIntegerStatus GetBooleanStatus "
    "GetStringStatus").split()}


def _pe_table(dll: bytes, path: Path) -> tuple[set[str], set[str]]:
    """The names a DLL exports and the DLLs it imports (MinGW's objdump)."""
    import re
    import shutil
    objdump = shutil.which("x86_64-w64-mingw32-objdump")
    if objdump is None:
        pytest.skip("x86_64-w64-mingw32-objdump is missing (Debian binutils-mingw-w64-x86-64)")
    path.write_bytes(dll)
    text = subprocess.run([objdump, "-p", str(path)], capture_output=True, text=True,
                          check=True).stdout
    table = text.split("[Ordinal/Name Pointer] Table", 1)[1].split("\n\n", 1)[0]
    exports = set(re.findall(r"\]\s+(\w+)", table))
    return exports, set(re.findall(r"DLL Name: (\S+)", text))


@pytest.mark.slow
@pytest.mark.parametrize("platform", CROSS)
def test_the_paper_loop_on_another_platform_equals_linux64(
        hosts, paper_system, platform, tmp_path):
    _need(platform)
    _, sysfile, steps, h = paper_system
    ref = _run(hosts["linux64"], sysfile, steps, h, tmp_path / "linux64.csv")
    got = _run(hosts[platform], sysfile, steps, h, tmp_path / f"{platform}.csv")
    header = (tmp_path / "linux64.csv").read_text().splitlines()[0].split(",")
    assert (tmp_path / f"{platform}.csv").read_text().splitlines()[0].split(",") == header
    _compare(ref, got, platform, header)
    assert ref.shape[1] > 20 and np.ptp(ref[:, 1:], axis=0).max() > 1.0   # a moving loop


# ------------------------------------------------------------------ (b) a guided REMUS 100
def _guided_inputs(steps: int) -> tuple[np.ndarray, np.ndarray]:
    """The guidance's force (N; a calm stretch where the reference speed falls below U_min,
    then turns and dives) and the autopilot's sensors, per step."""
    rng = np.random.default_rng(5)
    force = rng.normal(0.0, 10.0, (steps, 3))
    force[150:300] *= 1e-3
    force[300:] += [-40.0, 30.0, 5.0]
    sensors = np.column_stack([
        rng.uniform(1, 2, steps), rng.normal(0, .1, (steps, 2)),        # velocity
        rng.normal(0, 0.1, (steps, 2)), rng.uniform(-3, 3, steps),      # roll, pitch, yaw
        rng.normal(0, 0.05, (steps, 3)), 20 + rng.normal(0, 3, steps)])  # rates, depth
    return force, sensors


@pytest.fixture(scope="module")
def guided_system(tmp_path_factory):
    """The native guidance and autopilot of the straight-leader example (a REMUS 100
    vehicle's), for every platform; the guidance's set-points wired into the autopilot, the
    force and the sensors read from series files; every output recorded."""
    platforms = _buildable()
    from orchestrator.benchmarks.native import write_c_host_system
    from orchestrator.cosim.build import FMU_KINDS, build_fmus, interface_of
    from orchestrator.cosim.native_guidance import native_guidance_fmu
    from orchestrator.cosim.system import Component, Connection, SystemDescription
    from orchestrator.running.fmus import guidance_configs
    from orchestrator.scenario import load_scenario
    tmp = tmp_path_factory.mktemp("guided")
    configs = guidance_configs(load_scenario("docs/examples/straight-leader.toml"))
    py = build_fmus(None, tmp / "py", kinds=configs)
    fmus = {k: native_guidance_fmu(k, py[k], tmp / "native", platforms=platforms) for k in py}
    setpoints = ["speed", "course", "depth", "speed_rate", "course_rate", "depth_rate"]
    system = SystemDescription(
        "guided-remus100",
        tuple(Component(k, k, tuple(interface_of(FMU_KINDS[k], configs[k])))
              for k in ("guidance", "autopilot")),
        tuple(Connection("guidance", n, "autopilot", n) for n in setpoints), GUIDED_H, 30.0)
    md = {k: read_model_description(str(fmus[k])) for k in fmus}
    record = [(k, v.name) for k in ("guidance", "autopilot") for v in md[k].modelVariables
              if v.causality == "output"]
    sysfile = write_c_host_system(system, fmus, tmp / "unzipped", record=record)
    force, sensors = _guided_inputs(GUIDED_STEPS)
    vr = {k: {v.name: v.valueReference for v in md[k].modelVariables} for k in md}
    names = {"guidance": [f"u[{i}]" for i in (1, 2, 3)],
             "autopilot": ([f"velocity[{i}]" for i in (1, 2, 3)]
                           + [f"attitude[{i}]" for i in (1, 2, 3)]
                           + [f"rates[{i}]" for i in (1, 2, 3)] + ["measured_depth"])}
    lines = []
    for kind, data in (("guidance", force), ("autopilot", sensors)):
        for j, name in enumerate(names[kind]):
            f = tmp / "series" / f"{kind}-{name}.txt"
            f.parent.mkdir(exist_ok=True)
            f.write_text("\n".join(repr(float(v)) for v in data[:, j]) + "\n")
            lines.append(f"series {kind} {vr[kind][name]} {f.resolve()}")
    with sysfile.open("a") as fh:
        fh.write("\n".join(lines) + "\n")
    return fmus, sysfile, record


@pytest.mark.slow
@pytest.mark.parametrize("platform", CROSS)
def test_a_guided_remus_vehicle_on_another_platform_equals_linux64(
        hosts, guided_system, platform, tmp_path):
    _need(platform)
    fmus, sysfile, record = guided_system
    for fmu in fmus.values():
        assert {"linux64", platform} <= set(_binaries(fmu)) and validate_fmu(str(fmu)) == []
    ref = _run(hosts["linux64"], sysfile, GUIDED_STEPS, GUIDED_H, tmp_path / "linux64.csv")
    got = _run(hosts[platform], sysfile, GUIDED_STEPS, GUIDED_H, tmp_path / f"{platform}.csv")
    header = ["time", *(f"{c}.{n}" for c, n in record)]
    _compare(ref, got, platform, header)
    col = {name: j for j, name in enumerate(header)}
    # the vehicle turned and dived, the autopilot moved its fins and propeller
    assert np.ptp(ref[:, col["guidance.course"]]) > 1.0
    assert np.ptp(ref[:, col["guidance.depth"]]) > 0.1
    for out in ("rpm", "rudder", "stern"):
        assert np.ptp(ref[:, col[f"autopilot.{out}"]]) > 0.0, out


# ------------------------------------------------------------------ runs, and the CLI
@pytest.mark.slow
def test_a_runs_native_fmus_carry_the_hosts_binary_alone(tmp_path):
    """native_system without platforms (what ``auv-cosim run --fmus native`` calls) builds
    linux64 only: a run compiles nothing for another platform."""
    from orchestrator.interop.native import native_system
    from orchestrator.running import build, scenario_system
    from orchestrator.scenario import load_scenario
    sc = load_scenario("paper").with_run(T=1.0)
    ns = native_system(scenario_system(sc), build(sc, tmp_path / "py"), tmp_path / "native")
    assert ns.native_keys
    for key in ns.native_keys:
        assert set(_binaries(ns.fmus[key])) == {"linux64"}



@pytest.mark.slow
def test_export_native_builds_every_platform_with_a_compiler_and_says_which_is_absent(
        tmp_path):
    """By default every platform whose compiler is installed; a missing one (here win64's,
    hidden by CC_WIN64) is a line of the output, not an error."""
    _need("aarch64-linux")
    env = dict(os.environ, CC_WIN64=str(tmp_path / "no-mingw"))
    r = subprocess.run([sys.executable, "-m", "orchestrator", "export", "native", "--scenario",
                        "paper", "--out", str(tmp_path / "out")], capture_output=True,
                       text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    assert "binaries for linux64, aarch64-linux" in lines
    assert (f"win64: no cross compiler: '{tmp_path}/no-mingw' is not on PATH (install Debian's "
            f"gcc-mingw-w64-x86-64, or set CC_WIN64): its binary is not in the FMUs") in lines
    fmus = sorted((tmp_path / "out").glob("*Native.fmu"))
    assert len(fmus) == 3
    for fmu in fmus:
        assert set(_binaries(fmu)) == {"linux64", "aarch64-linux"}
    assert set(PLATFORMS) == set(ALL)
