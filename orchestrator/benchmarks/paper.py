"""Benchmark: co-simulation through the three FMUs against the monolithic numpy loop.

Both run in one process on the same scenario, seed and estimator, so their ratio is
meaningful on a shared, noisy machine; absolute figures are printed with the load.
"""
from __future__ import annotations

import ctypes
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from estimator_fmu.registry import DEFAULT_ESTIMATOR
from fmu_common.interface import element_names

from ..analysis.reference import run_monolithic
from ..cosim.instance import Extracted, FmuInstance, pythonfmu_safe_tempdir
from ..cosim.master import run_system
from ..cosim.system import closed_loop_system
from ..running import Method, make_setup, scenario_config, scenario_system
from ..scenario import Scenario

__all__ = ["benchmark", "benchmark_fleet", "benchmark_libcosim", "benchmark_startup",
           "benchmark_tools"]


def _fmi_call_costs(fmus: dict[str, Path], cfg: dict[str, Any],
                    reps: int = 20000) -> dict[str, float]:
    """Microseconds per raw FMI call on initialized instances (batched get/set)."""
    d = cfg["dims"]
    plant = closed_loop_system(cfg).component("plant")
    ex = Extracted(fmus)
    out: dict[str, float] = {}
    try:
        P = FmuInstance("plant", fmus["plant"], ex.dirs["plant"], "bench_plant")
        P.initialize(dict(plant.parameters), T=cfg["T"])
        names = [n for spec in plant.arrays("output") for n in element_names(spec.name, spec.shape)]
        vr = P.vrs(names)
        buf = (ctypes.c_double * len(names))()
        u_vr = P.vrs(element_names("u", (d["m"],)))
        u = (ctypes.c_double * d["m"])()
        a_vr, a_buf, a_uvr, a_u = map(ctypes.addressof, (vr, buf, u_vr, u))
        g, s, st, c = P.get_real, P.set_real, P.do_step, P.component
        t = time.perf_counter()
        for _ in range(reps):
            g(c, a_vr, len(names), a_buf)
        out[f"getReal_{len(names)}_values_us"] = (time.perf_counter() - t) / reps * 1e6
        t = time.perf_counter()
        for _ in range(reps):
            s(c, a_uvr, d["m"], a_u)
        out[f"setReal_{d['m']}_values_us"] = (time.perf_counter() - t) / reps * 1e6
        h = cfg["h"]
        t = time.perf_counter()
        for k in range(reps):
            st(c, k * h, h, 1)
        out["doStep_plant_us"] = (time.perf_counter() - t) / reps * 1e6
        P.close()
    finally:
        ex.cleanup()
    return out


def benchmark(sc: Scenario, mode: str = DEFAULT_ESTIMATOR, seed: int = 0) -> dict[str, Any]:
    """Time one run both ways; returns the figures (also printed by the CLI)."""
    from ..recording import write_rrd
    sc = sc.with_run(estimator=mode)
    cfg = scenario_config(sc)
    with tempfile.TemporaryDirectory(prefix="auv_bench_") as tmp:
        t = time.perf_counter()
        setup = make_setup(sc, Path(tmp) / "fmus")
        method = Method.of(sc)
        setup.fmus(method)                  # built (and, for --fmus native, compiled)
        fmus = setup.python_fmus(method)
        build_s = time.perf_counter() - t
        t = time.perf_counter()
        res = setup.run(method, seed)
        cosim_run_s = time.perf_counter() - t
        rrd = write_rrd(Path(tmp) / "bench.rrd", {mode: res.traces}, sc.h, recording_name="bench")
        t = time.perf_counter()
        timing: dict[str, float] = {}
        ref = run_monolithic(sc.system, sc.h, mode, seed, sc.steps, timing=timing)
        mono_s = time.perf_counter() - t
        calls = _fmi_call_costs(fmus, cfg)
    err = max(float(np.max(np.abs(ref[k] - res.traces[k]))) for k in ref)
    cosim_total = res.loop_s + rrd["rrd_s"]
    return {
        "scenario": sc.name, "mode": mode, "steps": sc.steps, "h": sc.h,
        "fmu_kind": sc.fmus, "build_s": build_s,
        "cosim_setup_s": cosim_run_s - res.loop_s,
        "cosim_loop_s": res.loop_s,
        "rrd_write_s": rrd["rrd_s"],
        "cosim_loop_plus_rrd_s": cosim_total,
        "monolithic_s": mono_s,
        "ratio_cosim_to_monolithic": cosim_total / mono_s,
        "ratio_loop_only": res.loop_s / mono_s,
        "monolithic_loop_s": timing["loop_s"],
        "ratio_loop_to_reference_loop": res.loop_s / timing["loop_s"],
        "rrd_fraction_of_run": rrd["rrd_s"] / cosim_total,
        "cosim_us_per_step": res.loop_s / sc.steps * 1e6,
        "monolithic_us_per_step": mono_s / sc.steps * 1e6,
        "max_abs_difference": err,
        "fmi_calls": calls,
        "loadavg": list(os.getloadavg()),
        "cpus": os.cpu_count(),
    }


def _model_description_bytes(fmu: Path) -> int:
    import zipfile
    with zipfile.ZipFile(fmu) as z:
        return z.getinfo("modelDescription.xml").file_size


def _instantiate_times(fmus: dict[str, Path], cfg: dict[str, Any]) -> dict[str, float]:
    """Seconds to instantiate + initialize each FMU (extraction excluded)."""
    ex = Extracted(fmus)
    out: dict[str, float] = {}
    try:
        for comp in closed_loop_system(cfg).components:
            t = time.perf_counter()
            inst = FmuInstance(comp.name, fmus[comp.fmu], ex.dirs[comp.fmu], f"bench_{comp.name}")
            inst.initialize(dict(comp.parameters), T=cfg["T"])
            out[comp.name] = time.perf_counter() - t
            inst.close()
    finally:
        ex.cleanup()
    return out


def benchmark_fleet(N: int, *, T: float = 300.0, mode: str = DEFAULT_ESTIMATOR,
                    tracking: str = "regulator",
                    seed: int = 0) -> dict[str, Any]:
    """Figures for a generated grid fleet of N REMUS 100 vehicles (orchestrator.scenario.generator):
    design and filter-gain time, FMU build time and modelDescription size, instantiate +
    initialize time, and the co-simulation loop against the monolithic loop (same process)."""
    from controller_fmu.regulator import tracking_law
    from estimator_fmu.registry import make_estimator
    from plant_model.discretization import discretize

    from ..scenario import scenario_from_dict
    from ..scenario.generator import grid_fleet

    sc = scenario_from_dict(grid_fleet(N, T=T), f"generated grid fleet N = {N}")
    sc = sc.with_run(estimator=mode, tracking=tracking)
    t = time.perf_counter()
    tracking_law(sc.system, tracking)
    design_s = time.perf_counter() - t
    t = time.perf_counter()
    model = discretize(sc.system, sc.h)
    sampling_s = time.perf_counter() - t
    t = time.perf_counter()
    make_estimator(sc.system, model, mode)
    filter_s = time.perf_counter() - t
    cfg = scenario_config(sc)
    with tempfile.TemporaryDirectory(prefix="auv_bench_") as tmp:
        t = time.perf_counter()
        setup = make_setup(sc, Path(tmp) / "fmus")
        method = Method.of(sc)
        fmus = setup.python_fmus(method)
        build_s = time.perf_counter() - t
        md_bytes = {k: _model_description_bytes(p) for k, p in fmus.items()}
        n_vars = {k: sum(1 for _ in _variables(p)) for k, p in fmus.items()}
        init_s = _instantiate_times(fmus, cfg)
        res = setup.run(method, seed)
        calls = _fmi_call_costs(fmus, cfg, reps=2000)
    timing: dict[str, float] = {}
    ref = run_monolithic(sc.system, sc.h, mode, seed, sc.steps, tracking, timing=timing)
    err = max(float(np.max(np.abs(ref[k] - res.traces[k]))) for k in ref)
    d = sc.system.dims
    return {
        "N": N, "steps": sc.steps, "h": sc.h, "T": sc.T, "mode": mode, "tracking": tracking,
        "dims": d, "state_size": d["n"] + d["r"] + d["l"],
        "design_s": design_s, "sampling_s": sampling_s, "filter_gain_s": filter_s,
        "build_s": build_s, "model_description_bytes": md_bytes, "variables": n_vars,
        "instantiate_initialize_s": init_s,
        "cosim_loop_s": res.loop_s, "cosim_us_per_step": res.loop_s / sc.steps * 1e6,
        "monolithic_loop_s": timing["loop_s"], "monolithic_setup_s": timing["setup_s"],
        "monolithic_us_per_step": timing["loop_s"] / sc.steps * 1e6,
        "ratio_loop": res.loop_s / timing["loop_s"],
        "fmi_overhead_us_per_step": (res.loop_s - timing["loop_s"]) / sc.steps * 1e6,
        "fmi_calls": calls, "max_abs_difference": err,
        "loadavg": list(os.getloadavg()), "cpus": os.cpu_count(),
    }


def _variables(fmu: Path) -> list:
    from fmpy import read_model_description
    return read_model_description(str(fmu)).modelVariables


def benchmark_libcosim(sc: Scenario, steps: int | None = None, *, mode: str | None = None,
                       seed: int | None = None, repeats: int = 3,
                       check: bool = True) -> dict[str, Any]:
    """Our fmpy master against libcosim (Open Simulation Platform, through libcosimpy) on
    the same FMUs, in one process.

    Exports the scenario (orchestrator.interop.osp.export_osp: the FMUs, OspSystemStructure.xml)
    once, then times ``repeats`` rounds, each running, in turn, our master with the
    Gauss-Seidel loop, our master with the Jacobi loop (libcosim's algorithm) and libcosim
    without observers, for ``steps`` steps (default the scenario's). Reported: the median
    and every round's microseconds per step of the stepping loop (initialization left out
    on both sides), and their ratios. ``check``: one more libcosim run with observers on
    every signal, compared with our Jacobi run (``libcosim_vs_jacobi_max_abs``, 0.0 when
    the traces are bit-identical).
    """
    import statistics

    from ..interop.libcosim import libcosim_version, quiet_libcosim, run_libcosim
    from ..interop.osp import export_osp

    quiet_libcosim()
    if mode is not None or seed is not None:
        sc = sc.with_run(estimator=mode, seed=seed)
    steps = int(steps or sc.steps)
    system = scenario_system(sc)
    rounds: dict[str, list[float]] = {"ours_gauss_seidel": [], "ours_jacobi": [], "libcosim": []}
    out: dict[str, Any] = {"scenario": sc.name, "mode": sc.estimator, "seed": sc.seed,
                           "steps": steps, "h": sc.h, "repeats": repeats}
    with tempfile.TemporaryDirectory(prefix="auv_bench_osp_") as tmp:
        t = time.perf_counter()
        paths = export_osp(sc, Path(tmp))
        out["export_s"] = time.perf_counter() - t
        fmus = {c.fmu: paths[c.fmu] for c in system.components}
        # the system the run step makes, on the exported files libcosim runs too

        def ours(n: int, coupling: str = "gauss-seidel") -> tuple[dict[str, Any], float]:
            traces, loop_s, _ = run_system(system, fmus, n, coupling=coupling)
            return traces, loop_s

        # warm-up (imports, first-call costs) outside the timed rounds
        ours(min(steps, 500))
        run_libcosim(paths["system"], system, min(steps, 500), record=False)
        jac = None
        for _ in range(max(1, repeats)):
            rounds["ours_gauss_seidel"].append(ours(steps)[1] / steps * 1e6)
            jac, loop_s = ours(steps, "jacobi")
            rounds["ours_jacobi"].append(loop_s / steps * 1e6)
            lc = run_libcosim(paths["system"], system, steps, record=False)
            rounds["libcosim"].append(lc["loop_s"] / lc["loop_steps"] * 1e6)
            out["libcosim_setup_s"] = lc["setup_s"]
            out["libcosim_init_and_first_step_s"] = lc["init_s"]
        if check:
            rec = run_libcosim(paths["system"], system, steps, record=True)
            out["libcosim_with_observers_us_per_step"] = rec["loop_s"] / rec["loop_steps"] * 1e6
            diff = max(float(np.max(np.abs(rec["traces"][k] - jac[k])))
                       for k in rec["traces"])
            out["libcosim_vs_jacobi_max_abs"] = diff
            out["libcosim_vs_jacobi_bit_identical"] = all(
                np.array_equal(rec["traces"][k], jac[k]) for k in rec["traces"])
    med = {k: statistics.median(v) for k, v in rounds.items()}
    out.update({
        "ours_gauss_seidel_us_per_step": med["ours_gauss_seidel"],
        "ours_jacobi_us_per_step": med["ours_jacobi"],
        "libcosim_us_per_step": med["libcosim"],
        "speedup_gauss_seidel_vs_libcosim": med["libcosim"] / med["ours_gauss_seidel"],
        "speedup_jacobi_vs_libcosim": med["libcosim"] / med["ours_jacobi"],
        "rounds_us_per_step": rounds,
        "versions": libcosim_version(),
        "loadavg": list(os.getloadavg()), "cpus": os.cpu_count(),
    })
    return out


def _simulate_ssp_us_per_step(ssp: Path, h: float, steps: int) -> float:
    """Microseconds per step of fmpy's simulate_ssp loop (its instantiation and freeing
    left out: fmpy's own instantiate/free functions are wrapped to mark the loop)."""
    import fmpy.ssp.simulation as fmpy_ssp

    from ..interop.ssp import fmpy_parameter_set
    marks: dict[str, float] = {}
    inst, free = fmpy_ssp.instantiate_fmu, fmpy_ssp.free_fmu

    def timed_instantiate(*a: Any, **kw: Any) -> None:
        inst(*a, **kw)
        marks["start"] = time.perf_counter()

    def timed_free(component: Any) -> None:
        marks.setdefault("end", time.perf_counter())
        free(component)

    fmpy_ssp.instantiate_fmu, fmpy_ssp.free_fmu = timed_instantiate, timed_free
    try:
        with pythonfmu_safe_tempdir():          # simulate_ssp unzips the FMUs there
            rows = len(fmpy_ssp.simulate_ssp(str(ssp), stop_time=steps * h, step_size=h,
                                             parameter_set=fmpy_parameter_set(ssp)))
    finally:
        fmpy_ssp.instantiate_fmu, fmpy_ssp.free_fmu = inst, free
    return (marks["end"] - marks["start"]) / rows * 1e6


def benchmark_tools(sc: Scenario, steps: int = 5000, repeats: int = 3) -> dict[str, Any]:
    """Microseconds per step of the same FMUs in our orchestrator (Gauss-Seidel and
    Jacobi), libcosim through libcosimpy, and fmpy's simulate_ssp, in one run (medians of
    ``repeats`` alternating rounds; loops only, initialization left out everywhere)."""
    import statistics

    from ..interop.osp import export_osp
    from ..interop.ssp import export_ssp

    out = benchmark_libcosim(sc, steps, repeats=repeats, check=False)
    with tempfile.TemporaryDirectory(prefix="auv_bench_tools_") as tmp:
        paths = export_osp(sc, Path(tmp) / "osp")
        fmus = {c.fmu: paths[c.fmu] for c in scenario_system(sc).components}
        ssp = export_ssp(sc, Path(tmp) / "system.ssp", fmus=fmus)
        _simulate_ssp_us_per_step(ssp, sc.h, min(steps, 500))          # warm-up
        rounds = [_simulate_ssp_us_per_step(ssp, sc.h, steps) for _ in range(max(1, repeats))]
    out["simulate_ssp_us_per_step"] = statistics.median(rounds)
    out["rounds_us_per_step"]["simulate_ssp"] = rounds
    out["speedup_gauss_seidel_vs_simulate_ssp"] = (out["simulate_ssp_us_per_step"]
                                                   / out["ours_gauss_seidel_us_per_step"])
    return out


def benchmark_startup(sc: Scenario, repeats: int = 3) -> dict[str, Any]:
    """Wall time of ``auv-cosim run --quiet`` as a subprocess (interpreter start to exit)
    with a warm and with an empty FMU cache, and with native FMUs (``--fmus native``: the
    compiled master; warm cache) when a C compiler is there, against the in-process loop
    of the monolithic reference (:mod:`orchestrator.analysis.reference`), rounds
    alternating; medians.

    Parameters
    ----------
    sc : Scenario
        The scenario to run (a built-in name or a file, with its T and h).
    repeats : int
        Rounds.

    Returns
    -------
    dict
        ``run_warm_s``, ``run_cold_s``, ``run_native_s`` (None without a compiler),
        ``reference_loop_s``, ``ratio_run_to_reference_loop``,
        ``ratio_native_run_to_reference_loop``, ``import_cli_s``, ``python_s``, the rounds,
        the load and the CPU count.
    """
    import shutil
    import statistics
    import subprocess
    import sys

    def wall(cmd: list[str], env: dict[str, str] | None = None) -> float:
        t = time.perf_counter()
        subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
        return time.perf_counter() - t

    native = shutil.which(os.environ.get("CC", "cc")) is not None
    rounds: dict[str, list[float]] = {"run_warm_s": [], "run_cold_s": [], "reference_loop_s": [],
                                      "import_cli_s": [], "python_s": []}
    if native:
        rounds["run_native_s"] = []
    py = sys.executable
    with tempfile.TemporaryDirectory(prefix="auv_bench_start_") as tmp:
        spec = sc.name if sc.source.startswith("built-in scenario") else sc.source
        run = [py, "-m", "orchestrator", "run", "--quiet", "--scenario", spec,
               "--T", repr(sc.T), "--h", repr(sc.h), "--out", str(Path(tmp) / "out"),
               "--force"]
        wall(run)                                       # fills the user's FMU cache
        if native:
            wall([*run, "--fmus", "native"])
        for i in range(max(1, repeats)):
            rounds["run_warm_s"].append(wall(run))
            if native:
                rounds["run_native_s"].append(wall([*run, "--fmus", "native"]))
            cold = dict(os.environ, AUV_COSIM_CACHE=str(Path(tmp) / f"cache{i}"))
            rounds["run_cold_s"].append(wall(run, cold))
            timing: dict[str, float] = {}
            run_monolithic(sc.system, sc.h, sc.estimator, sc.seed, sc.steps, sc.tracking,
                           timing=timing)
            rounds["reference_loop_s"].append(timing["loop_s"])
            rounds["import_cli_s"].append(wall([py, "-c", "import orchestrator.cli"]))
            rounds["python_s"].append(wall([py, "-c", "pass"]))
    med = {k: statistics.median(v) for k, v in rounds.items()}
    med.setdefault("run_native_s", None)
    return {"scenario": sc.name, "mode": sc.estimator, "steps": sc.steps, "h": sc.h,
            "repeats": repeats, **med,
            "ratio_run_to_reference_loop": med["run_warm_s"] / med["reference_loop_s"],
            "ratio_native_run_to_reference_loop": (
                None if med["run_native_s"] is None
                else med["run_native_s"] / med["reference_loop_s"]),
            "rounds": rounds, "loadavg": list(os.getloadavg()), "cpus": os.cpu_count()}
