"""The master reproduces the golden traces (tests/data/make_golden.py): every built-in
scenario x estimator mode x tracking law x coupling, short horizons, seed 7, noise stream 2.

One set for every machine: bit for bit on the BLAS kernels it was recorded with, elsewhere
to 1e-12 of each trace's scale (an estimate's scale is its estimator's largest estimate:
tests/support/kernels.py), which test_noise_factor.py shows holds across kernels."""
from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parent / "data"
sys.path.insert(0, str(DATA))
from make_golden import blas_kernel, golden_runs, matches  # noqa: E402

from orchestrator.cosim.master import CosimError  # noqa: E402
from support.loop import run_cosimulation  # noqa: E402

META = json.loads((DATA / "golden_traces.json").read_text())
_NPZ = DATA / "golden_traces.npz"
SAME_PLATFORM = matches(META["platform"], blas_kernel())
#: traces whose tolerance takes the scale of the whole estimate (tests/support/kernels.py)
ESTIMATES = ("xhat", "what", "zhat")


@pytest.fixture(scope="module")
def golden():
    with np.load(_NPZ) as z:
        return {k: z[k] for k in z.files}


@pytest.mark.slow
@pytest.mark.parametrize("scenario", list(META["horizons"]))
def test_master_reproduces_golden_traces(scenario, golden, built_scenario):
    # the goldens were recorded before the protocol form existed: fleets in the in-plant form
    fmus, cfg = built_scenario(scenario, None if scenario == "paper" else "in-plant")
    compared = 0
    for key, name, mode, tracking, coupling, steps in golden_runs():
        if name != scenario:
            continue
        if key in META["refused"]:
            with pytest.raises(CosimError, match="classical estimator needs C with full column rank"):
                run_cosimulation(fmus, cfg, mode=mode, seed=META["seed"], steps=steps,
                                 tracking=tracking, coupling=coupling)
            continue
        res = run_cosimulation(fmus, cfg, mode=mode, seed=META["seed"], steps=steps,
                               tracking=tracking, coupling=coupling)
        want = {k.rsplit("|", 1)[1]: v for k, v in golden.items() if k.startswith(key + "|")}
        assert set(res.traces) == set(want), key
        estimate_scale = max(float(np.abs(want[k]).max(initial=0.0)) for k in ESTIMATES
                             if k in want)
        for sig, ref in want.items():
            got = res.traces[sig]
            if SAME_PLATFORM:
                assert np.array_equal(got, ref), f"{key}: trace {sig} differs from the golden one"
            else:
                scale = estimate_scale if sig in ESTIMATES else float(np.abs(ref).max())
                np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * scale,
                                           err_msg=f"{key}: trace {sig}")
            compared += 1
    assert compared >= 10
    if not SAME_PLATFORM:
        warnings.warn(f"golden traces were recorded on {META['platform']}, this machine is "
                      f"{blas_kernel()}: compared to 1e-12, not bit for bit", stacklevel=1)
