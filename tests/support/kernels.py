"""OpenBLAS kernels for the reproducibility tests: which ones this CPU can run, a run of the
real command under one of them, and the comparison of two recordings.

OpenBLAS (bundled with numpy and scipy) picks its kernels by CPU at load time;
``OPENBLAS_CORETYPE`` forces another one the CPU supports. threadpoolctl reports the one that
was loaded, so a test can check that the kernel it asked for is the one that ran.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from functools import cache
from pathlib import Path

import numpy as np

#: kernels tried, newest first (OpenBLAS's names for OPENBLAS_CORETYPE); Prescott loads the
#: Katmai (SSE) kernels, so it is checked by what threadpoolctl reports, not by its name
CANDIDATES = ("SkylakeX", "Haswell", "Sandybridge", "Nehalem", "Prescott")

BIN = Path(sys.executable).parent


def kernel_env(kernel: str | None, threads: int = 1) -> dict[str, str]:
    """The environment of a child process running ``kernel`` (None: the CPU's own) with
    ``threads`` BLAS threads."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    env.update(OPENBLAS_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads),
               MKL_NUM_THREADS=str(threads))
    if kernel is not None:
        env["OPENBLAS_CORETYPE"] = kernel
    return env


def loaded_kernel(env: dict[str, str]) -> tuple[str, int]:
    """(architecture, threads) that numpy's OpenBLAS reports in a child with ``env``."""
    code = ("import json, numpy, scipy.linalg; from threadpoolctl import threadpool_info; "
            "i = [x for x in threadpool_info() if x.get('internal_api') == 'openblas']; "
            "print(json.dumps([i[0].get('architecture'), i[0].get('num_threads')]))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout
    arch, threads = json.loads(out.strip().splitlines()[-1])
    return str(arch), int(threads)


@cache
def usable_kernels() -> tuple[tuple[str, str], ...]:
    """(OPENBLAS_CORETYPE, architecture loaded) of each candidate this CPU runs, distinct
    architectures only, the CPU's own first."""
    seen: dict[str, str] = {}
    own, _ = loaded_kernel(kernel_env(None))
    seen[own] = ""
    for name in CANDIDATES:
        arch, _ = loaded_kernel(kernel_env(name))
        if arch not in seen and arch.lower() != own.lower():
            seen[arch] = name
    return tuple((name, arch) for arch, name in seen.items())


def auv_cosim(args: list[str], env: dict[str, str], timeout: float = 300) -> None:
    """Run ``auv-cosim args`` in ``env``; fail with its stderr if it does not exit 0."""
    proc = subprocess.run([str(BIN / "auv-cosim"), *args], env=env, capture_output=True,
                          text=True, timeout=timeout)
    assert proc.returncode == 0, f"auv-cosim {' '.join(args)}: {proc.stderr[-2000:]}"


def group_of(entity: str) -> str:
    """The group whose scale an entity's tolerance takes: the estimates of one estimator
    (``vehicles/2/current/kalman/estimate`` and ``vehicles/2/state/kalman/estimate``, or the
    paper's ``state/1/kalman/estimate`` and ``disturbance/1/kalman/estimate``) share it,
    every other entity is its own group."""
    if entity.endswith("/estimate"):
        return re.sub(r"/[^/]+/([^/]+)/estimate$", r"/*/\1/estimate", entity)
    return entity


def worst_difference(a: dict, b: dict) -> tuple[float, str]:
    """The largest |a - b| over every scalar series of two recordings
    (:func:`orchestrator.recording.reader.read_rrd_scalars` results) relative to its group's
    scale (:func:`group_of`: the largest |value| of the group in ``a``), and where."""
    assert set(a) == set(b), "the two recordings hold other series"
    scale: dict[str, float] = {}
    for k, (_, _, v) in a.items():
        g = group_of(k)
        scale[g] = max(scale.get(g, 0.0), float(np.abs(v).max(initial=0.0)))
    worst, where = 0.0, ""
    for k, (step, _, v) in a.items():
        step_b, _, w = b[k]
        assert np.array_equal(step, step_b) and v.shape == w.shape, k
        d = float(np.abs(v - w).max(initial=0.0)) / max(scale[group_of(k)], 1e-300)
        if d > worst:
            worst, where = d, k
    return worst, where
