"""``auv-cosim bench native``: microseconds per step of the paper's loop with native FMUs.

Measured in one run, on one machine, for the same scenario and number of steps:

- ``python``: the three pythonfmu FMUs in our master (fmpy, ctypes);
- ``native_ctrl_est``: native controller and estimator, pythonfmu plant, in our master;
- ``native_master``: every FMU native, in our Python master (about 10 ctypes calls per
  step);
- ``native_compiled``: every FMU native, in our compiled master (the same step plan in
  C, :mod:`orchestrator.cosim.native_master`; target at most 3 us/step);
- ``native_c_host``: every FMU native, in the C host of orchestrator/interop/native_host
  (no Python at all);
- ``native_ecos``: every FMU native, in the ecos engine (C++), its own loop timer, no CSV;
- ``fused_numpy``: the same closed loop as one matrix-vector product per step
  ([Phi Gam] [X; eta], orchestrator.analysis.prediction.closed_loop), the lower bound of
  a Python program.

:func:`benchmark_native_fleet` times a per-vehicle fleet of native FMUs (formation-100,
distributed: 301 FMUs) for a short T in both masters: ms/step and the 300 s run projected
from it (target at most 1 ms/step).

Speeds are figures, not assertions: the machine is shared and noisy.
"""
from __future__ import annotations

import os
import re
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..cosim.master import run_system
from ..interop.c_host import C_HOST_SOURCE
from ..interop.native import export_native, native_system
from ..scenario import Scenario

__all__ = ["benchmark_native", "benchmark_native_fleet", "c_host_binary", "fused_loop_us",
           "write_c_host_system"]

ROOT = Path(__file__).resolve().parents[2]
C_HOST = C_HOST_SOURCE


def fused_loop_us(sc: Scenario, steps: int) -> float:
    """us/step of X+ = [Phi Gam] [X; eta] (one gemv per step, the noise drawn beforehand)."""
    from controller_fmu.regulator import tracking_law
    from estimator_fmu.registry import make_estimator
    from plant_model.discretization import discretize
    from plant_model.plant import NoiseStream

    from ..analysis.prediction import closed_loop
    model = discretize(sc.system, sc.h)
    est = make_estimator(sc.system, model, sc.estimator)
    Phi, Gam, _, _ = closed_loop(model, est, tracking_law(sc.system, sc.tracking).Ks)
    M = np.ascontiguousarray(np.hstack([Phi, Gam]))
    n = Phi.shape[0]
    eta = NoiseStream.all_rows(model, sc.seed, steps)
    buf = np.zeros(M.shape[1])
    out = np.empty((steps, n))
    t0 = time.perf_counter()
    for k in range(steps):
        buf[n:] = eta[k]
        M.dot(buf, out=out[k])
        buf[:n] = out[k]
    return (time.perf_counter() - t0) / steps * 1e6


def c_host_binary(out_dir: Path) -> Path:
    """orchestrator/interop/native_host/c_host.c compiled into ``out_dir`` (cc, -O2, FMI
    headers from fmpy; the folder is created if missing)."""
    import fmpy
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    exe = Path(out_dir) / "c_host"
    inc = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(["cc", "-O2", "-std=c99", "-Wall", "-Wextra", f"-I{inc}", "-o", str(exe),
                    str(C_HOST), "-ldl", "-lm"], check=True, capture_output=True, text=True)
    return exe


def write_c_host_system(system: Any, fmus: dict[str, Path], unzip_root: Path,
                        record: list[tuple[str, str]] | None = None) -> Path:
    """The C host's system file for ``system`` (orchestrator/interop/native_host/README.md):
    every FMU unzipped under ``unzip_root``, the parameters, the connections, the recorded
    variables.

    Parameters
    ----------
    system : SystemDescription
        The system (native components).
    fmus : dict[str, Path]
        FMU key -> .fmu.
    unzip_root : Path
        Where the FMUs are unzipped (one folder per FMU file).
    record : list[tuple[str, str]] or None, optional
        (component, variable) to write to the CSV; default every output of every component.

    Returns
    -------
    Path
        The system file (``unzip_root / "system.txt"``).
    """
    import zipfile

    from fmpy import read_model_description
    lines, vrs, dirs = [], {}, {}
    for key in dict.fromkeys(c.fmu for c in system.components):
        d = unzip_root / Path(fmus[key]).stem
        with zipfile.ZipFile(fmus[key]) as z:
            z.extractall(d)
        md = read_model_description(str(fmus[key]))
        dirs[key] = (md, d)
        vrs[key] = {v.name: (v.valueReference, v.type, v.causality) for v in md.modelVariables}
    for c in system.components:
        md, d = dirs[c.fmu]
        lines.append(f"fmu {c.name} {md.coSimulation.modelIdentifier} {md.guid} {d.resolve()}")
        for name, value in c.parameters.items():
            vr, typ, _ = vrs[c.fmu][name]
            kind = "real" if typ == "Real" else "int"
            lines.append(f"{kind} {c.name} {vr} {float(value) if kind == 'real' else int(value)!r}")
    for con in system.scalar_connections(active_only=True):
        (a, out), (b, inp) = con.source, con.target
        lines.append(f"connect {a} {vrs[system.component(a).fmu][out][0]} "
                     f"{b} {vrs[system.component(b).fmu][inp][0]}")
    if record is None:
        record = [(c.name, n) for c in system.components
                  for n, (_, t, caus) in vrs[c.fmu].items() if caus == "output" and t == "Real"]
    for comp, name in record:
        lines.append(f"record {comp} {vrs[system.component(comp).fmu][name][0]}")
    path = unzip_root / "system.txt"
    path.write_text("\n".join(lines) + "\n")
    return path


def _ecos_us(ssp: Path, h: float, steps: int, workdir: Path) -> float | None:
    """us/step of the ecos engine's own loop (its last progress line), or None."""
    try:
        import ecospy
    except ImportError:
        return None
    exe = Path(ecospy.__file__).parent / "binaries" / "ecos"
    if not os.access(exe, os.X_OK):
        os.chmod(exe, 0o755)
    r = subprocess.run([str(exe), "simulate", "--path", str(ssp), "--stopTime",
                        repr(steps * h), "--stepSize", repr(h), "--noParallel", "--noCsv"],
                       cwd=workdir, env={"PATH": "/usr/bin:/bin"}, capture_output=True,
                       text=True)
    found = re.findall(r"simulated ([0-9.]+)s in ([0-9.]+)s", r.stdout + r.stderr)
    if r.returncode != 0 or not found:
        return None
    sim, wall = (float(x) for x in found[-1])
    return wall / (sim / h) * 1e6


def benchmark_native(sc: Scenario, steps: int = 20000) -> dict[str, Any]:
    """The figures of the module docstring for ``steps`` steps of ``sc`` (stacked).

    Parameters
    ----------
    sc : Scenario
        A single-system or stacked scenario.
    steps : int, optional
        Steps per loop.

    Returns
    -------
    dict[str, Any]
        us/step per configuration (None where a tool is missing) and the load average.
    """
    from ..running import build, scenario_system
    sc = sc.with_run(T=steps * sc.h)
    out: dict[str, Any] = {"scenario": sc.name, "mode": sc.estimator, "h": sc.h,
                           "steps": steps, "loadavg": list(os.getloadavg()),
                           "cpus": os.cpu_count()}
    with tempfile.TemporaryDirectory(prefix="auv_bench_native_") as tmp:
        t = Path(tmp)
        system = scenario_system(sc)
        py = build(sc, t / "py")
        mixed = native_system(system, py, t / "mixed", ("estimator", "controller"))
        full = native_system(system, py, t / "full")
        for key, (s, f, master) in {
                "python": (system, py, "python"),
                "native_ctrl_est": (mixed.system, mixed.fmus, "python"),
                "native_master": (full.system, full.fmus, "python"),
                "native_compiled": (full.system, full.fmus, "native")}.items():
            _, loop_s, _ = run_system(s, f, steps, master=master)
            out[key] = loop_s / steps * 1e6
        try:
            exe = c_host_binary(t)
            sysfile = write_c_host_system(full.system, full.fmus, t / "unzipped", record=[])
            r = subprocess.run([str(exe), str(sysfile), str(steps), repr(sc.h),
                                str(t / "c.csv")], capture_output=True, text=True, env={})
            m = re.search(r"us_per_step\s+([0-9.eE+-]+)", r.stdout)
            out["native_c_host"] = float(m.group(1)) if m and r.returncode == 0 else None
        except (OSError, subprocess.CalledProcessError):
            out["native_c_host"] = None
        paths = export_native(sc, t / "export")
        out["native_ecos"] = _ecos_us(paths["ssp"], sc.h, steps, t)
        out["fused_numpy"] = fused_loop_us(sc, steps)
    return out


def benchmark_native_fleet(name: str = "formation-100", T: float = 5.0,
                          run_T: float = 300.0) -> dict[str, Any]:
    """ms/step of a per-vehicle fleet of native FMUs (distributed architecture) in the
    compiled and the Python master, over ``T`` s, and the ``run_T`` s run projected.

    Parameters
    ----------
    name : str, optional
        A fleet scenario.
    T : float, optional
        Simulated time of each timed run, s.
    run_T : float, optional
        The run to project, s.

    Returns
    -------
    dict[str, Any]
        ``setup_s`` (design, FMU builds, native FMUs: what a run does before its loop),
        ``components``, ``calls_per_step``, per master ``<master>_ms_per_step`` and
        ``<master>_projected_loop_s`` (``run_T`` / h steps), ``traces_equal`` (bit for bit),
        the load average and the CPUs.
    """
    from ..running.systems import make_setup
    from ..scenario import load_scenario
    sc = load_scenario(name).with_run(T=T, deployment="per-vehicle",
                                      architecture="distributed", fmus="native")
    out: dict[str, Any] = {"scenario": name, "T": T, "h": sc.h, "steps": sc.steps,
                           "run_T": run_T, "loadavg": list(os.getloadavg()),
                           "cpus": os.cpu_count()}
    with tempfile.TemporaryDirectory(prefix="auv_bench_fleet_") as tmp:
        t0 = time.perf_counter()
        setup = make_setup(sc, Path(tmp))
        method = setup.methods[0]
        system, fmus = setup.system(method, sc.seed), setup.fmus(method)
        out["setup_s"] = time.perf_counter() - t0
        out["components"] = len(system.components)
        traces = {}
        for master in ("native", "python"):
            traces[master], loop_s, info = run_system(system, fmus, sc.steps, master=master)
            out[f"{master}_ms_per_step"] = loop_s / sc.steps * 1e3
            out[f"{master}_projected_loop_s"] = loop_s / sc.steps * round(run_T / sc.h)
            out["calls_per_step"] = len(info["calls_per_step"])
        out["traces_equal"] = all(np.array_equal(traces["native"][k], traces["python"][k])
                                  for k in traces["python"])
    out["loadavg_after"] = list(os.getloadavg())
    return out
