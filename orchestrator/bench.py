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

from fmu_common.interface import element_names
from .master import (PLANT_OUTPUTS, FmuInstance, _Extracted, fmu_parameters, run_cosimulation,
                     signal_names)
from .reference import run_monolithic
from .scenario import Scenario
from .workflow import build, scenario_config

__all__ = ["benchmark"]


def _fmi_call_costs(fmus: dict[str, Path], cfg: dict[str, Any], reps: int = 20000) -> dict[str, float]:
    """Microseconds per raw FMI call on initialized instances (batched get/set)."""
    d = cfg["dims"]
    ex = _Extracted(fmus)
    out: dict[str, float] = {}
    try:
        P = FmuInstance("plant", fmus["plant"], ex.dirs["plant"], "bench_plant")
        P.initialize(fmu_parameters("plant", cfg), T=cfg["T"])
        names = signal_names(PLANT_OUTPUTS, d)
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


def benchmark(sc: Scenario, mode: str = "kalman", seed: int = 0) -> dict[str, Any]:
    """Time one run both ways; returns the figures (also printed by the CLI)."""
    from .recording import write_rrd

    cfg = scenario_config(sc)
    with tempfile.TemporaryDirectory(prefix="auv_bench_") as tmp:
        t = time.perf_counter()
        fmus = build(sc, Path(tmp) / "fmus")
        build_s = time.perf_counter() - t
        t = time.perf_counter()
        res = run_cosimulation(fmus, cfg, mode=mode, seed=seed, steps=sc.steps)
        cosim_run_s = time.perf_counter() - t
        rrd = write_rrd(Path(tmp) / "bench.rrd", {mode: res.traces}, sc.h, recording_name="bench")
        t = time.perf_counter()
        ref = run_monolithic(sc.system, sc.h, mode, seed, sc.steps)
        mono_s = time.perf_counter() - t
        calls = _fmi_call_costs(fmus, cfg)
    err = max(float(np.max(np.abs(ref[k] - res.traces[k]))) for k in ref)
    cosim_total = res.loop_s + rrd["rrd_s"]
    return {
        "scenario": sc.name, "mode": mode, "steps": sc.steps, "h": sc.h,
        "build_s": build_s,
        "cosim_setup_s": cosim_run_s - res.loop_s,
        "cosim_loop_s": res.loop_s,
        "rrd_write_s": rrd["rrd_s"],
        "cosim_loop_plus_rrd_s": cosim_total,
        "monolithic_s": mono_s,
        "ratio_cosim_to_monolithic": cosim_total / mono_s,
        "ratio_loop_only": res.loop_s / mono_s,
        "rrd_fraction_of_run": rrd["rrd_s"] / cosim_total,
        "cosim_us_per_step": res.loop_s / sc.steps * 1e6,
        "monolithic_us_per_step": mono_s / sc.steps * 1e6,
        "max_abs_difference": err,
        "fmi_calls": calls,
        "loadavg": list(os.getloadavg()),
        "cpus": os.cpu_count(),
    }
