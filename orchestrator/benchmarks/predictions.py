"""Benchmark of the predictions over acoustic links (``bench --predictions``): what the
second moment and the critical-loss search cost, cold and from the cache.

Per architecture, on the scenario's ``[network]``: the networked loop's size (states,
error coordinates, links, message cycle in steps), one application of the cycle map L
(:class:`orchestrator.analysis.acoustic.stability.CycleMap`), the stationary predictions a
run makes (the second-moment radius and the expected cost over the window,
:func:`orchestrator.running.network.network_predictions`) and the critical-loss search
(:func:`orchestrator.analysis.acoustic.stability.critical_loss`), each with the prediction
cache off; then both again on a new loop object with the cache filled (a second run), and
the figures. Wall-clock seconds on a shared machine: compare ratios of one run, with the
load average printed next to them.
"""
from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from estimator_fmu.registry import DEFAULT_ESTIMATOR

if TYPE_CHECKING:
    from ..scenario import Scenario

__all__ = ["benchmark_predictions"]


def _timed(f: Any) -> tuple[Any, float]:
    t = time.perf_counter()
    out = f()
    return out, time.perf_counter() - t


def benchmark_predictions(sc: Scenario, architectures: Sequence[str] = ("centralized",
                                                                   "distributed"),
                          mode: str = DEFAULT_ESTIMATOR, tracking: str = "regulator"
                          ) -> dict[str, Any]:
    """Figures per architecture (module docstring).

    Parameters
    ----------
    sc : Scenario
        A per-vehicle fleet scenario with a ``[network]``.
    architectures : sequence of str, optional
        The laws to time.
    mode, tracking : str, optional
        Estimator and tracking law.

    Returns
    -------
    dict[str, Any]
        ``rows`` (one per architecture: sizes and seconds) and the load.
    """

    out: dict[str, Any] = {"loadavg": list(os.getloadavg()), "cpus": os.cpu_count(),
                           "rows": []}
    old = os.environ.get("AUV_COSIM_PREDICTION_CACHE")
    try:
        for arch in architectures:
            out["rows"].append(_row(sc.with_run(architecture=arch), arch, mode, tracking))
    finally:
        if old is None:
            os.environ.pop("AUV_COSIM_PREDICTION_CACHE", None)
        else:
            os.environ["AUV_COSIM_PREDICTION_CACHE"] = old
    out["loadavg_after"] = list(os.getloadavg())
    return out


def _row(sc: Scenario, arch: str, mode: str, tracking: str) -> dict[str, Any]:
    """One architecture's figures (the cache switched by the environment)."""
    from ..analysis.acoustic.cycle import _Compiler
    from ..analysis.acoustic.stability import CycleMap, critical_loss
    from ..running.network import network_predictions, network_setup
    from ..running.setup import Method

    method = Method(mode, mode, tracking, arch)
    os.environ["AUV_COSIM_PREDICTION_CACHE"] = "0"
    setup, setup_s = _timed(lambda: network_setup(sc, method))
    net = setup.net
    cmap = CycleMap(_Compiler(net, error_only=True))
    X = np.eye(cmap.n)
    cmap(X)
    _, apply_s = _timed(lambda: [cmap(X) for _ in range(10)])
    pred, stationary_s = _timed(lambda: network_predictions(sc, setup))
    (p, note), critical_s = _timed(lambda: critical_loss(net))
    with tempfile.TemporaryDirectory() as cache:
        os.environ["AUV_COSIM_PREDICTION_CACHE"] = cache
        fill = network_setup(sc, method)
        network_predictions(sc, fill)
        critical_loss(fill.net)
        again = network_setup(sc, method)          # a second run's loop
        _, hit_s = _timed(lambda: (network_predictions(sc, again), critical_loss(again.net)))
    return {"architecture": arch, "states": net.n, "error_states": cmap.n,
            "links": len(net.R), "cycle_steps": net.period, "setup_s": setup_s,
            "cycle_map_ms": 100.0 * apply_s, "stationary_s": stationary_s,
            "critical_loss_s": critical_s, "cached_s": hit_s,
            "second_moment_radius": pred[0].spectral_radius,
            "cost_rate_window": pred[1].cost_rate, "critical_loss": p,
            "critical_loss_note": note}
