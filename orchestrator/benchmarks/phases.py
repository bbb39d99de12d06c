"""``auv-cosim bench --phases``: where a whole ``auv-cosim run`` spends its time.

The run is a subprocess (``python -m orchestrator run --quiet ...``, interpreter start to
exit); its ``summary.json`` gives the split of the command's own clock
(:mod:`orchestrator.running.phases`: build, design, predictions, instantiate, loop,
statistics, recording, other), and the rest of the subprocess's wall time is start-up
(imports, parsing, the scenario) and the end (the staged folder's swap, exit). The target
of issue 36: a native fleet command spends at most as long outside its loop as inside it.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

__all__ = ["RUN_OPTIONS", "benchmark_phases", "run_argv"]

#: the bench's scenario options that ``run`` takes too (attribute -> flag)
RUN_OPTIONS = {"scenario": "--scenario", "deployment": "--deployment",
               "architecture": "--architecture", "latency": "--latency", "period": "--period",
               "loss": "--loss", "receiver": "--receiver", "T": "--T", "h": "--h",
               "fmus": "--fmus", "estimator": "--estimator", "seed": "--seed",
               "tracking": "--tracking"}


def run_argv(options: dict[str, Any]) -> list[str]:
    """``run``'s options for the given values (None left out), in :data:`RUN_OPTIONS` order.

    Parameters
    ----------
    options : dict[str, Any]
        Attribute -> value (an argparse namespace's ``vars``).

    Returns
    -------
    list[str]
        E.g. ``["--scenario", "formation-100", "--T", "300.0"]``.
    """
    out: list[str] = []
    for key, flag in RUN_OPTIONS.items():
        value = options.get(key)
        if value is not None:
            out += [flag, str(value)]
    return out


def benchmark_phases(options: dict[str, Any]) -> dict[str, Any]:
    """Run ``auv-cosim run`` with ``options`` as a subprocess and split its time.

    Parameters
    ----------
    options : dict[str, Any]
        The scenario options (:data:`RUN_OPTIONS`' attributes).

    Returns
    -------
    dict[str, Any]
        ``argv`` (run's options), ``command_s`` (the subprocess, start to exit),
        ``phases_s`` (the summary's split), ``startup_and_exit_s`` (command_s minus the
        summary's wall_s), ``outside_loop_s``, ``loop_s``, ``outside_to_loop`` (their
        ratio; target at most 1), ``steps``, ``loadavg`` before and ``loadavg_after``,
        ``cpus``.

    Raises
    ------
    RuntimeError
        If the run fails (its last error lines).
    """
    argv = run_argv(options)
    out: dict[str, Any] = {"argv": argv, "loadavg": list(os.getloadavg()),
                           "cpus": os.cpu_count()}
    with tempfile.TemporaryDirectory(prefix="auv_bench_phases_") as tmp:
        folder = Path(tmp) / "run"
        cmd = [sys.executable, "-m", "orchestrator", "run", "--quiet", *argv,
               "--out", str(folder)]
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True)
        out["command_s"] = time.perf_counter() - t0
        if r.returncode != 0:
            raise RuntimeError(f"auv-cosim run {' '.join(argv)} failed (exit {r.returncode}): "
                               + r.stderr.strip()[-500:])
        summary = json.loads((folder / "summary.json").read_text())
    ph = summary["timing"]["phases_s"]
    out["phases_s"] = ph
    out["wall_s"] = summary["wall_s"]
    out["steps"] = summary["steps"]
    out["startup_and_exit_s"] = out["command_s"] - summary["wall_s"]
    out["loop_s"] = ph["loop"]
    out["outside_loop_s"] = out["command_s"] - ph["loop"]
    out["outside_to_loop"] = out["outside_loop_s"] / ph["loop"] if ph["loop"] > 0 else None
    out["loadavg_after"] = list(os.getloadavg())
    return out
