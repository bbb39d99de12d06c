"""``auv-cosim bench --campaign``: campaign throughput and the design cache's gain.

- runs per hour of the paper scenario (T = 300 s, h = 0.01 s) with the FMU engine on 1 and 2
  local workers, and with the numpy engine; for each, the whole command (cluster start
  included) and the tasks alone;
- the overhead per task: Dask scheduling, moving the task and its rows, writing the rows,
  from a campaign of ten-step runs, (tasks time x workers - time inside the runs) / tasks;
- the design cache at N = 50 (a generated grid fleet): per-seed wall time of an FMU run
  with the cache off (every FMU instance solves its design) and on (solved once per point).
"""
from __future__ import annotations

import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

__all__ = ["benchmark_campaign"]


def _campaign(tmp: Path, name: str, text: str, **kw: Any) -> dict[str, Any]:
    from ..campaign.runner import run_campaign
    spec = tmp / f"{name}.toml"
    spec.write_text(text)
    out = tmp / name
    t0 = time.perf_counter()
    status = run_campaign(spec, out, progress=False, log=lambda s: None, **kw)
    wall = time.perf_counter() - t0
    summary = json.loads((out / "campaign.json").read_text())
    assert status == 0, f"campaign {name} ended with status {status}"
    import pyarrow.parquet as pq
    rows = pq.read_table(out / "results.parquet").to_pylist()
    return {"wall_s": wall, "runs": len(rows), "summary": summary, "rows": rows}


def _throughput(r: dict[str, Any]) -> dict[str, float]:
    tasks_s = r["summary"]["cluster"]["tasks_wall_s"]
    return {"runs": r["runs"], "command_s": r["wall_s"], "tasks_s": tasks_s,
            "runs_per_hour": 3600 * r["runs"] / r["wall_s"],
            "runs_per_hour_tasks": 3600 * r["runs"] / tasks_s}


def design_cache_gain(N: int = 50, T: float = 1.0, seeds: int = 2) -> dict[str, Any]:
    """Per-seed wall time of FMU runs of an N-vehicle grid fleet, cache off and on.

    Parameters
    ----------
    N : int
        Vehicles.
    T : float
        Simulated time per run, s.
    seeds : int
        Runs per measurement.

    Returns
    -------
    dict[str, Any]
        ``per_seed_off_s``, ``per_seed_on_s`` (mean wall time of one run), ``design_s``
        (the point's design, solved once per task), ``saved_per_seed_s``.
    """
    from plant_model.memo import clear_caches

    from ..campaign.tasks import Task, run_task
    from ..scenario import scenario_from_dict
    from ..scenario.generator import grid_fleet

    sc = scenario_from_dict(grid_fleet(N, T=T), f"grid-{N}")
    task = Task(0, {"vehicles.count": N}, sc, "gauss-seidel", "fmu", tuple(range(seeds)),
                tuple(f"k{i}" for i in range(seeds)))
    out: dict[str, Any] = {"N": N, "T": T, "seeds": seeds, "states": sc.system.n + sc.system.r
                           + sc.system.l}
    old = os.environ.get("AUV_COSIM_DESIGN_CACHE")
    try:
        for label, flag in (("off", "0"), ("on", "1")):
            os.environ["AUV_COSIM_DESIGN_CACHE"] = flag
            clear_caches()
            rows = run_task(task)
            bad = [r["error"] for r in rows if r["status"] != "ok"]
            if bad:
                raise RuntimeError(bad[0])
            out[f"per_seed_{label}_s"] = sum(r["wall_s"] for r in rows) / len(rows)
            out[f"design_{label}_s"] = rows[0]["design_s"]
    finally:
        if old is None:
            os.environ.pop("AUV_COSIM_DESIGN_CACHE", None)
        else:
            os.environ["AUV_COSIM_DESIGN_CACHE"] = old
        clear_caches()
    out["saved_per_seed_s"] = out["per_seed_off_s"] - out["per_seed_on_s"]
    return out


def benchmark_campaign(seeds: int = 8, numpy_seeds: int = 64, N: int = 50) -> dict[str, Any]:
    """The figures of the module docstring.

    Parameters
    ----------
    seeds : int
        Runs of the paper scenario per FMU measurement.
    numpy_seeds : int
        Runs for the numpy engine.
    N : int
        Fleet size of the design-cache measurement.

    Returns
    -------
    dict[str, Any]
    """
    paper = 'base = "paper"\nseeds = "0-{last}"\n'
    out: dict[str, Any] = {"loadavg": list(os.getloadavg()), "cpus": os.cpu_count()}
    with tempfile.TemporaryDirectory(prefix="auv_bench_campaign_") as tmp_name:
        tmp = Path(tmp_name)
        for workers in (1, 2):
            r = _campaign(tmp, f"fmu{workers}", paper.format(last=seeds - 1), workers=workers)
            out[f"fmu_{workers}_workers"] = _throughput(r)
        r = _campaign(tmp, "numpy", paper.format(last=numpy_seeds - 1), workers=1,
                      engine="numpy")
        out["numpy_1_worker"] = _throughput(r)
        out["numpy_1_worker"]["us_per_step_per_seed"] = (
            1e6 * sum(x["loop_s"] for x in r["rows"]) / r["runs"] / 30000)
        tiny = 'base = "paper"\nseeds = "0-19"\nseeds_per_task = 1\n[sweep]\n' \
               '"simulation.T" = [0.1]\n'
        r = _campaign(tmp, "overhead", tiny, workers=2)
        cl = r["summary"]["cluster"]
        inside = sum(x["wall_s"] + x["design_s"] + x.get("build_s", 0.0) for x in r["rows"])
        out["overhead"] = {"tasks": cl["tasks"], "tasks_s": cl["tasks_wall_s"],
                           "inside_runs_s": inside,
                           "per_task_s": (cl["tasks_wall_s"] * cl["workers"] - inside)
                           / cl["tasks"]}
    out["design_cache"] = design_cache_gain(N)
    out["loadavg_after"] = list(os.getloadavg())
    return out
