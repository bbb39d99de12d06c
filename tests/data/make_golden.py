"""Record the golden traces the master must reproduce (tests/test_golden_traces.py).

Run from the repository root with the master to be frozen:
``.venv/bin/python tests/data/make_golden.py``. Writes ``golden_traces.npz`` (every trace of
every built-in scenario x estimator mode x tracking law x coupling, short horizons, seed 7)
and ``golden_traces.json`` (the horizons and the BLAS kernels the traces were computed
with). One BLAS thread, as the orchestrator runs.

One set for every machine: since noise stream 2 (plant_model/noise_factor.py) a seed's
traces differ between BLAS kernels only in their rounding, so the test compares bit for bit
on the recorded kernels and to 1e-12 of each trace's scale elsewhere. The set in the
repository was recorded on 2026-11-29 with noise stream 2 (the sets of stream 1, one per
kernel, are gone with it).
"""
from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"         # before numpy: the thread count changes the last bits
import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent.parent))
sys.path.insert(0, str(HERE.parent))          # the tests' support package

#: steps per built-in scenario (short: the traces are committed)
HORIZONS = {"paper": 200, "formation-4": 60, "formation-20": 12}
MODES = ("kalman", "classical", "ideal")
TRACKINGS = ("lq", "regulator")
COUPLINGS = ("gauss-seidel", "jacobi")


def blas_kernel() -> dict:
    """What decides the last bits of a result: numpy's and scipy's BLAS builds and the CPU
    model (OpenBLAS picks its kernels by CPU)."""
    import platform

    import scipy
    cpu = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                if ln.startswith("model name")), platform.processor())
    from threadpoolctl import threadpool_info
    return {"numpy": np.__version__, "scipy": scipy.__version__,
            "numpy_blas": np.show_config(mode="dicts")["Build Dependencies"]["blas"].get("version"),
            "scipy_blas": scipy.show_config(mode="dicts")["Build Dependencies"]["blas"].get("version"),
            "cpu": cpu, "machine": platform.machine(),
            # the kernels OpenBLAS picked for this CPU: one model name ("AMD EPYC") covers
            # CPUs with and without AVX-512, whose kernels give other last bits, and a fleet's
            # noise factors (eigenvectors of repeated eigenvalues) other directions
            "blas_kernels": sorted({str(i.get("architecture")) for i in threadpool_info()
                                    if i.get("internal_api") == "openblas"})}


def matches(recorded: dict, here: dict) -> bool:
    """Whether golden traces recorded on ``recorded`` are expected bit for bit ``here``:
    the same packages, CPU and BLAS kernels."""
    return all(recorded.get(k) == here.get(k) for k in set(recorded) | set(here))


def golden_runs():
    """(key, scenario, mode, tracking, coupling, steps) of every golden run."""
    for name, steps in HORIZONS.items():
        for mode in MODES:
            for tracking in TRACKINGS:
                for coupling in COUPLINGS:
                    yield f"{name}|{mode}|{tracking}|{coupling}", name, mode, tracking, coupling, steps


def _scenario(name: str):
    """A built-in scenario as the goldens run it: fleets in the in-plant consensus form
    (they were recorded before the protocol form existed)."""
    import tomllib

    from orchestrator.scenario import SCENARIO_DIR, load_scenario, scenario_from_dict
    if name == "paper":
        return load_scenario(name)
    data = tomllib.loads((SCENARIO_DIR / f"{name}.toml").read_text())
    data["graph"]["consensus"] = "in-plant"
    return scenario_from_dict(data, f"built-in scenario '{name}' (in-plant)")


def main() -> None:
    """Record the goldens with the current master."""
    from orchestrator.cosim.master import CosimError
    from orchestrator.running import build, scenario_config
    from plant_model.noise_factor import NOISE_STREAM
    from support.loop import run_cosimulation

    arrays: dict[str, np.ndarray] = {}
    refused: dict[str, str] = {}
    built: dict[str, tuple] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for key, name, mode, tracking, coupling, steps in golden_runs():
            if name not in built:
                sc = _scenario(name)
                built[name] = (build(sc, Path(tmp) / name), scenario_config(sc))
            fmus, cfg = built[name]
            try:
                res = run_cosimulation(fmus, cfg, mode=mode, seed=7, steps=steps,
                                       tracking=tracking, coupling=coupling)
            except CosimError as exc:       # e.g. the classical law on a fleet's C
                refused[key] = str(exc).split(";")[0]
                print(key, "refused:", refused[key])
                continue
            for sig, arr in res.traces.items():
                arrays[f"{key}|{sig}"] = np.ascontiguousarray(arr)
            print(key, {s: a.shape for s, a in res.traces.items()}, flush=True)
    stem = HERE / "golden_traces"
    np.savez_compressed(stem.with_suffix(".npz"), **arrays)
    stem.with_suffix(".json").write_text(json.dumps(
        {"seed": 7, "horizons": HORIZONS, "noise_stream": NOISE_STREAM,
         "platform": blas_kernel(), "refused": refused}, indent=1) + "\n")


if __name__ == "__main__":
    main()
