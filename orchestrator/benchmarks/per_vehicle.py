"""Benchmark of the per-vehicle deployment against fleet size N (``bench --fleet ...
--deployment per-vehicle``): where the time goes, and how it grows with N.

Per N, for a generated survey grid (:func:`orchestrator.scenario.generator.survey_grid_fleet`,
ceil(sqrt(N)) columns): the time to build the FMUs (one per kind), the largest
modelDescription (constant in N for the distributed architecture, O(N) inputs for the
centralized one), the design (per vehicle, as each controller FMU solves it, summed; or the
stacked one), instantiate + initialize of all 1 + 3 N FMUs, the co-simulation's us/step,
and the same loop as one matrix recursion in numpy (the monolithic reference of the
distributed loop, with a sparse step matrix) with the largest difference between the two;
the stacked Lyapunov prediction is timed separately (it is O(N^3) where the rest is O(N)).
"""
from __future__ import annotations

import math
import os
import tempfile
import time
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from estimator_fmu.registry import DEFAULT_ESTIMATOR

__all__ = ["benchmark_per_vehicle"]


def _md_bytes(fmu: Path) -> int:
    with zipfile.ZipFile(fmu) as z:
        return z.getinfo("modelDescription.xml").file_size


def benchmark_per_vehicle(N: int, *, architecture: str = "distributed", T: float = 20.0,
                          mode: str = DEFAULT_ESTIMATOR, tracking: str = "regulator",
                          seed: int = 0, predict: bool = True) -> dict[str, Any]:
    """Figures of one fleet size (module docstring).

    Parameters
    ----------
    N : int
        Number of vehicles.
    architecture : str, optional
        ``distributed`` or ``centralized``.
    T : float, optional
        Simulated time, s.
    mode, tracking : str, optional
        Estimator mode and tracking law.
    seed : int, optional
        Noise seed.
    predict : bool, optional
        Also time the stacked Lyapunov prediction (distributed).

    Returns
    -------
    dict[str, Any]
        The figures (seconds, bytes, us/step), the machine's load average and CPU count.
    """
    from controller_fmu.vehicle_law import vehicle_law

    from ..analysis.distributed import fleet_agents
    from ..running.setup import Method
    from ..running.systems import make_setup
    from ..scenario import scenario_from_dict
    from ..scenario.generator import survey_grid_fleet

    cols = max(1, math.ceil(math.sqrt(N)))
    sc = scenario_from_dict(survey_grid_fleet(N, columns=cols, T=T), f"survey grid N = {N}")
    sc = sc.with_run(estimator=mode, tracking=tracking, architecture=architecture)
    out: dict[str, Any] = {"N": N, "architecture": architecture, "steps": sc.steps, "h": sc.h,
                           "T": sc.T, "mode": mode, "tracking": tracking}
    t = time.perf_counter()
    if architecture == "distributed":
        agents, _, leader = fleet_agents(sc.fleet)
        for a in agents:
            vehicle_law(A=a.A, B1=a.B, B2=a.E, C=a.C, K=a.Kw, Q=a.Q, R=a.R, F=leader["F"],
                        H=leader["H"], offset=a.offset, tracking=tracking,
                        regulator=sc.distributed.regulator, h=sc.h)
    else:
        from controller_fmu.regulator import tracking_law
        tracking_law(sc.system, tracking)
    out["design_s"] = time.perf_counter() - t
    with tempfile.TemporaryDirectory(prefix="auv_bench_pv_") as tmp:
        pv = make_setup(sc, Path(tmp) / "fmus")
        t = time.perf_counter()
        fmus = pv.fmus(Method.of(sc))
        out["build_s"] = time.perf_counter() - t
        out["model_description_bytes"] = {k: _md_bytes(p) for k, p in fmus.items()}
        t = time.perf_counter()
        res = pv.run(Method.of(sc), seed)
        wall = time.perf_counter() - t
    out["cosim_loop_s"] = res.loop_s
    out["setup_s"] = wall - res.loop_s          # extract, instantiate, initialize, plan
    out["cosim_us_per_step"] = res.loop_s / sc.steps * 1e6
    out["fmu_instances"] = 1 + 3 * N
    if architecture == "distributed":
        from ..analysis.per_vehicle import distributed_loop_of
        t = time.perf_counter()
        loop = distributed_loop_of(sc, mode, tracking, sc.distributed)
        out["loop_assembly_s"] = time.perf_counter() - t
        from ..analysis.per_vehicle import distributed_reference
        timing: dict[str, float] = {}
        ref = distributed_reference(sc, loop, seed, sc.steps, timing)
        loop_s = timing["loop_s"]
        out["monolithic_us_per_step"] = loop_s / sc.steps * 1e6
        out["ratio"] = res.loop_s / loop_s
        out["max_abs_difference_u"] = float(np.max(np.abs(ref["u"] - res.traces["u"])))
        if predict:
            from ..analysis.distributed_verdict import predict_cost
            t = time.perf_counter()
            out["predicted_cost_rate"] = predict_cost(loop).cost_rate
            out["prediction_s"] = time.perf_counter() - t
    out["loadavg"] = list(os.getloadavg())
    out["cpus"] = os.cpu_count()
    return out
