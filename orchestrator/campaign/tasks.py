"""One task: one design point's batch of seeds, run on a worker; its result is one row per run.

The design is solved once per task, not once per seed. The FMU engine runs the point through
the one run step (:class:`orchestrator.running.setup.RunSetup`: any deployment, links,
vehicle model, FMU kind and coupling; its predictions once per task, each seed's statistics
as ``auv-cosim run`` computes them), and the FMUs of every seed find the same sampled model,
filter gains and law in the process's design cache (:mod:`plant_model.memo`: pythonfmu
slaves run in this interpreter and import the same modules). The numpy engine (the stacked
linear loop only, :func:`.engine_numpy.numpy_unsupported`) samples the model, solves the law
and the estimator once (:func:`point_design`) and runs all seeds on the one design.

A run that fails (an impossible design, a refused FMU call, anything raised) becomes a row
with ``status = "error"`` and the message; the other seeds and tasks go on.
"""
from __future__ import annotations

import json
import os
import shutil
import socket
import tempfile
import time
from dataclasses import dataclass, field
from typing import Any

from ..analysis.weight_search import path_verdict
from ..scenario import Scenario
from .results import TRACKING_FIGURES

__all__ = ["Task", "PointDesign", "point_design", "run_task", "error_rows"]


@dataclass(frozen=True)
class Task:
    """What a worker runs: the point's scenario, the seeds, their run keys, the engine."""

    point: int
    params: dict[str, Any]
    scenario: Scenario | None
    coupling: str
    engine: str                        #: 'fmu' or 'numpy'
    seeds: tuple[int, ...]
    keys: tuple[str, ...]
    role: str = "run"                  #: 'run', or 'check' (an FMU re-run of a numpy run)
    error: str | None = None           #: the point's error, if it has no scenario
    note: str | None = None            #: why a numpy point went to the FMU engine

    def pending(self, done: set[str]) -> Task | None:
        """This task without the runs whose keys are in ``done`` (None if none remain).

        Parameters
        ----------
        done : set[str]
            Keys of finished runs.

        Returns
        -------
        Task or None
        """
        keep = [(s, k) for s, k in zip(self.seeds, self.keys) if k not in done]
        if not keep:
            return None
        return Task(self.point, self.params, self.scenario, self.coupling, self.engine,
                    tuple(s for s, _ in keep), tuple(k for _, k in keep), self.role,
                    self.error, self.note)


@dataclass
class PointDesign:
    """The design of one point, solved once for all its seeds."""

    model: Any                         #: DiscreteModel
    est: Any                           #: LinearEstimator
    Ks: Any                            #: control gain, u = -Ks [xhat; what; zhat]
    k0: int                            #: first sample of the statistics window
    prediction: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0               #: time to solve it, s


def point_design(sc: Scenario, coupling: str = "gauss-seidel") -> PointDesign:
    """Sample the model, solve the tracking law, make the estimator and predict the cost.

    Prediction as :func:`orchestrator.running.simulate` makes it: the stationary
    Lyapunov prediction of the exact loop (plus, for a fleet, the mean motion over the
    statistics window [k0, K)), or of the Jacobi-coupled loop for ``coupling='jacobi'``;
    k0 from 5 time constants of the slowest closed-loop mode (at most T/2).

    Parameters
    ----------
    sc : Scenario
        The point's scenario (its estimator and tracking law).
    coupling : str, optional
        The master's coupling.

    Returns
    -------
    PointDesign

    Raises
    ------
    ModelError
        If the design or the estimator does not exist.
    """
    from controller_fmu.regulator import tracking_law
    from estimator_fmu.registry import make_estimator
    from plant_model.discretization import discretize

    from ..analysis.prediction import predict_stationary
    from ..analysis.summary import stats_window

    t0 = time.perf_counter()
    model = discretize(sc.system, sc.h)
    Ks = tracking_law(sc.system, sc.tracking).Ks
    est = make_estimator(sc.system, model, sc.estimator)
    pred = predict_stationary(sc.system, model, est, Ks)
    k0 = stats_window(sc.T, sc.h, pred.settling_time)
    if coupling == "jacobi":
        from ..analysis.jacobi import predict_stationary_jacobi
        pj = predict_stationary_jacobi(sc.system, model, est, Ks)
        out = {k: pj[k] for k in ("rms_e", "rms_u", "cost_rate")}
        out["note"] = pj["reason"]
    else:
        if pred.cost_rate is not None and sc.fleet is not None:
            pred = predict_stationary(sc.system, model, est, Ks, window=(k0, sc.steps))
        out = {"rms_e": pred.rms_e, "rms_u": pred.rms_u, "cost_rate": pred.cost_rate,
               "note": pred.reason}
    return PointDesign(model, est, Ks, k0, out, time.perf_counter() - t0)


def _base_row(task: Task, seed: int, key: str, engine: str) -> dict[str, Any]:
    sc = task.scenario
    return {"run_key": key, "role": task.role, "point": task.point,
            "params": json.dumps(task.params), "seed": int(seed),
            "engine": engine, "status": "error", "error": None,
            "scenario": sc.name if sc else None, "T": sc.T if sc else None,
            "h": sc.h if sc else None, "estimator": sc.estimator if sc else None,
            "tracking": sc.tracking if sc else None, "coupling": task.coupling,
            "deployment": sc.deployment if sc else None,
            "architecture": sc.architecture if sc else None,
            "fmus": sc.fmus if sc else None,
            "engine_note": task.note}


def _finish(row: dict[str, Any], versions: str, wall_s: float) -> dict[str, Any]:
    row.update(wall_s=wall_s, host=socket.gethostname(), pid=os.getpid(), versions=versions)
    return row


def _message(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 2000 else text[:1997] + "..."


def error_rows(task: Task, message: str, versions: str = "{}") -> list[dict[str, Any]]:
    """One error row per run of ``task``, all with ``message``.

    Parameters
    ----------
    task : Task
    message : str
        The one-line error.
    versions : str, optional
        JSON of the package versions.

    Returns
    -------
    list[dict[str, Any]]
    """
    rows = []
    for seed, key in zip(task.seeds, task.keys):
        row = _base_row(task, seed, key, task.engine)
        row["error"] = message
        rows.append(_finish(row, versions, 0.0))
    return rows


def _stats_row(row: dict[str, Any], stats: dict[str, Any], pred: dict[str, Any],
               window_start_s: float, design_s: float) -> None:
    row.update(status="ok", cost_rate=stats["cost_rate"], rms_e=stats["rms_e"],
               rms_u=stats["rms_u"], mean_e=stats["mean_e"],
               predicted_cost_rate=pred["cost_rate"], predicted_rms_e=pred["rms_e"],
               predicted_rms_u=pred["rms_u"], prediction_note=pred["note"],
               window_start_s=window_start_s, design_s=design_s)


def _tracking_figures(stats: dict[str, Any]) -> dict[str, Any]:
    if "segments" not in stats:
        return {}
    seg = stats["segments"]
    return {k: seg.get(k) for k in TRACKING_FIGURES}


def run_task(task: Task) -> list[dict[str, Any]]:
    """Run every seed of ``task`` (on a worker); never raises for a failing run.

    Parameters
    ----------
    task : Task

    Returns
    -------
    list[dict[str, Any]]
        One row per seed: the keys of :func:`error_rows` plus, for a run that finished,
        ``cost_rate``, ``rms_e``, ``rms_u``, ``mean_e``, the predicted values, the
        statistics window, ``design_s`` (the point's design, once per task) and
        ``loop_s``; for a fleet through the FMUs also :data:`TRACKING_FIGURES`.
    """
    from ..analysis.summary import versions
    ver = json.dumps(versions(), sort_keys=True)
    if task.scenario is None:
        return error_rows(task, task.error or "the point has no scenario", ver)
    if task.engine != "numpy":
        return _fmu_rows(task, ver)
    t0 = time.perf_counter()
    try:
        design = point_design(task.scenario, task.coupling)
    except Exception as exc:                      # an impossible design: rows, not a crash
        return error_rows(task, _message(exc), ver)
    return _numpy_rows(task, design, ver, time.perf_counter() - t0)


def _numpy_rows(task: Task, design: PointDesign, ver: str,
                setup_s: float) -> list[dict[str, Any]]:
    from .engine_numpy import run_batch
    sc = task.scenario
    assert sc is not None
    t0 = time.perf_counter()
    try:
        stats = run_batch(design.model, design.est, design.Ks, sc.system.initial_state(),
                          sc.system.Q, sc.system.R, list(task.seeds), sc.steps, design.k0)
    except Exception as exc:
        return error_rows(task, _message(exc), ver)
    wall = (time.perf_counter() - t0) / len(task.seeds)
    rows = []
    for seed, key, st in zip(task.seeds, task.keys, stats):
        row = _base_row(task, seed, key, "numpy")
        _stats_row(row, st, design.prediction, design.k0 * design.model.h, design.seconds)
        row["loop_s"] = wall
        rows.append(_finish(row, ver, wall + setup_s / len(task.seeds)))
    return rows


def _fmu_rows(task: Task, ver: str) -> list[dict[str, Any]]:
    from ..running.setup import Method, stats_context
    from ..running.statistics import RunRecorder, RunStatistics
    from ..running.systems import make_setup
    sc = task.scenario
    assert sc is not None
    work = tempfile.mkdtemp(prefix="auv_campaign_")
    rows = []
    try:
        t_design = time.perf_counter()
        try:
            setup = make_setup(sc, work, coupling=task.coupling)
            method = Method.of(sc)
            pred = setup.predictions(method)
            design_s = time.perf_counter() - t_design
            t_build = time.perf_counter()
            setup.fmus(method)
            build_s = time.perf_counter() - t_build
        except Exception as exc:                  # an impossible design: rows, not a crash
            return error_rows(task, _message(exc), ver)
        expected = {"rms_e": pred.window.rms_e, "rms_u": pred.window.rms_u,
                    "cost_rate": pred.window.cost_rate, "note": pred.window.reason}
        formation = stats_context(sc)
        verdict = path_verdict(sc.design) if formation is not None else {}
        for seed, key in zip(task.seeds, task.keys):
            row = _base_row(task, seed, key, "fmu")
            row.update(verdict)
            t0 = time.perf_counter()
            try:
                recorder = RunRecorder(RunStatistics(sc, pred.k0, formation))
                res = setup.run(method, seed, recorder=recorder)
                stats = recorder.statistics.result()
                _stats_row(row, stats, expected, pred.k0 * sc.h, design_s)
                row.update(_tracking_figures(stats))
                row["loop_s"] = res.loop_s
            except Exception as exc:
                row["error"] = _message(exc)
            row["build_s"] = build_s
            rows.append(_finish(row, ver, time.perf_counter() - t0))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return rows
