"""``bench --remus``: what the nonlinear REMUS 100 costs (docs/remus100-6dof.md).

In one run, on the same machine load: one derivative evaluation and one communication
step (autopilots, RK4, reference velocity) in the numpy definition and in the compiled
kernel; fmi2DoStep of the vehicle FMUs under fmpy, the nonlinear ``AuvRemus6dof`` against
the linear ``AuvVehicle`` (us per step and vehicle); the kernel's compile time in a fresh
process (numba, cached on disk after the first time unless the FMU's resources are
unpacked to a new folder, as in every FMU instance's first process).
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from estimator_fmu.registry import DEFAULT_ESTIMATOR

__all__ = ["benchmark_remus"]


def _per_call(f: Any, count: int) -> float:
    """Median over 5 rounds of the time per call of f(), us."""
    rounds = []
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(count):
            f()
        rounds.append((time.perf_counter() - t0) / count * 1e6)
    return float(np.median(rounds))


def _fmu_step_us(fmus: dict[str, Path], system: Any, component: str, steps: int) -> float:
    """us per fmi2DoStep of one instance of ``component``'s FMU, inputs held."""
    from ..cosim.instance import Extracted, FmuInstance
    comp = system.component(component)
    ex = Extracted({comp.fmu: fmus[comp.fmu]})
    try:
        inst = FmuInstance(component, fmus[comp.fmu], ex.dirs[comp.fmu], f"bench_{component}")
        inst.initialize(dict(comp.parameters), T=steps * system.h + 1.0)
        h = system.h
        for k in range(50):                              # warm up (numba compiles here)
            inst.do_step(inst.component, k * h, h, 1)
        t0 = time.perf_counter()
        for k in range(50, 50 + steps):
            inst.do_step(inst.component, k * h, h, 1)
        us = (time.perf_counter() - t0) / steps * 1e6
        inst.close()
        return us
    finally:
        ex.cleanup()


def benchmark_remus(steps: int = 20_000) -> dict[str, Any]:
    """The figures of the module docstring."""
    from plant_model.remus100 import kernel
    from plant_model.remus100.autopilot import AutopilotGains, ForceCommandedRemus
    from plant_model.remus100.dynamics import Remus100, derivative
    from plant_model.vehicle_models import plants_of
    from plant_model.vehicles import remus100

    from ..cosim.build import build_fmus
    from ..cosim.per_vehicle import build_configs, per_vehicle_configs, per_vehicle_system
    from ..scenario import load_scenario

    load = os.getloadavg()
    v = Remus100(current=(0.1, -0.1, 0.0))
    cur = np.array(v.current)
    x = np.zeros(15)
    x[[2, 6, 14]] = 20.0, 1.5, 900.0
    cmd, out = np.array([0.1, -0.05, 1000.0]), np.empty(15)
    p, g = kernel.pack(v), kernel.pack_gains(AutopilotGains())
    kernel.derivative(p, x, cmd, cur, out)
    r: dict[str, Any] = {"jit": kernel.JIT, "loadavg": list(load), "cpus": os.cpu_count()}
    r["derivative_numpy_us"] = _per_call(lambda: derivative(v, x, cmd), 300)
    r["derivative_kernel_us"] = _per_call(lambda: kernel.derivative(p, x, cmd, cur, out), 20_000)
    lin = remus100(cruise_speed=1.5).parameters
    M, D = np.array(lin["total_mass"]), np.array(lin["damping"])
    ref = ForceCommandedRemus(v, M, D, x)
    F = np.array([16.0, 2.0, 0.0])
    r["step_numpy_us"] = _per_call(lambda: ref.step(F, 0.01, 1), 100)
    xs, vr, integ, c3 = x.copy(), ref.v_ref.copy(), np.zeros(2), np.zeros(3)
    r["step_kernel_us"] = _per_call(lambda: kernel.force_commanded_step(
        p, g, xs, vr, integ, F, cur, M, D, 0.01, 1, c3), 20_000)
    code = ("import time; t0 = time.perf_counter(); import numpy as np; "
            "from plant_model.remus100 import kernel as k; "
            "from plant_model.remus100.dynamics import Remus100; "
            "from plant_model.remus100.autopilot import AutopilotGains; "
            "x = np.zeros(15); x[6] = 1.5; c = np.zeros(3); "
            "k.force_commanded_step(k.pack(Remus100()), k.pack_gains(AutopilotGains()), x, "
            "np.ones(3), np.zeros(2), np.ones(3), np.zeros(3), np.ones(3), np.ones(3), 0.01, 1, "
            "c); print(time.perf_counter() - t0)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        root = str(Path(__file__).resolve().parents[2])
        cold = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              cwd=root, env=env, timeout=300)
        warm = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              cwd=root, env=env, timeout=300)
    r["compile_cold_s"] = float(cold.stdout.strip() or "nan")
    r["compile_cached_s"] = float(warm.stdout.strip() or "nan")
    with tempfile.TemporaryDirectory() as tmp:
        for model in plants_of("remus100"):
            sc = load_scenario("formation-4").with_run(
                T=10.0, deployment="per-vehicle", architecture="distributed"
            ).with_vehicle_model(model)
            cfgs = per_vehicle_configs(sc, "distributed", estimator=DEFAULT_ESTIMATOR, seed=0,
                                       tracking=sc.tracking)
            fmus = build_fmus(None, Path(tmp) / model, kinds=build_configs(cfgs))
            system = per_vehicle_system(sc, cfgs, "distributed")
            r[f"fmu_step_us_{model}"] = _fmu_step_us(fmus, system, "vehicle_1", steps)
    r["loadavg_after"] = list(os.getloadavg())
    return r
