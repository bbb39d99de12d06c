"""The paper loop seen from the tests: parameter values and output names of one component
for a configuration, and :func:`run_cosimulation` (the three FMUs of a configuration run
by the master, without a scenario)."""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from fmu_common.interface import element_names
from orchestrator.cosim.master import RunResult, run_system
from orchestrator.cosim.system import closed_loop_system


def fmu_parameters(component: str, config: dict[str, Any]) -> dict[str, Any]:
    """Scalar parameter values (FMI names) the master sets on one component of the loop."""
    return dict(closed_loop_system(config).component(component).parameters)


def output_names(component: str, config: dict[str, Any]) -> list[str]:
    """FMI scalar names of all outputs of one component, in the FMU's order."""
    comp = closed_loop_system(config).component(component)
    return [n for s in comp.arrays("output") for n in element_names(s.name, s.shape)]


def run_cosimulation(fmus: dict[str, Path], config: dict[str, Any], *, mode: str, seed: int,
                     steps: int, progress: Any = False, tracking: str | None = None,
                     coupling: str = "gauss-seidel", stop: Any = None) -> RunResult:
    """Run the paper's loop (:func:`orchestrator.cosim.system.closed_loop_system`) of the three FMUs for ``steps`` steps.

    Parameters
    ----------
    fmus : dict[str, Path]
        'plant', 'estimator', 'controller' -> .fmu path, built for ``config``.
    config : dict[str, Any]
        The FMUs' configuration (:func:`orchestrator.cosim.build.fmu_config`); the
        communication step is ``config['h']``, s.
    mode : str
        The estimator mode.
    seed : int
        Seed of the plant's noise.
    steps : int
        Number of communication steps.
    progress : Any, optional
        As in :func:`orchestrator.cosim.master.run_system`.
    tracking : str or None, optional
        The controller's law ('lq' or 'regulator'); default the configuration's.
    coupling : str, optional
        'gauss-seidel' (the exact discrete-time loop, default) or 'jacobi' (what libcosim
        does; module docstring).
    stop : StopFlag, optional
        See :func:`orchestrator.cosim.master.run_system`.

    Returns
    -------
    RunResult
        The traces, timings and run information.

    Raises
    ------
    CosimError
        If an FMU refuses a call.
    """
    t0 = time.perf_counter()
    cfg = dict(config, estimator=mode, seed=int(seed),
               tracking=tracking or config.get("tracking", "lq"))
    system = closed_loop_system(cfg)
    traces, loop_s, info = run_system(system, fmus, steps, coupling=coupling,
                                      progress=progress, instance_suffix=f"_{mode}_{seed}",
                                      stop=stop)
    return RunResult(mode=mode, seed=int(seed), h=system.h, traces=traces,
                     wall_s=time.perf_counter() - t0, loop_s=loop_s, coupling=coupling,
                     info=info)
