"""``run`` and ``compare``: every method on every seed through the one run step, the
statistics, the predictions, the recording and ``summary.json``."""
from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from plant_model.linalg_checks import ModelError
from plant_model.noise_factor import NOISE_STREAM

from ..analysis.formation import formation_summary
from ..analysis.full_information import fleet_bound, fleet_comparison
from ..analysis.summary import method_summary, stationarity_note, stationary_horizon, versions
from ..analysis.tracking_segments import segment_summary
from ..atomic import write_text_atomically
from ..cosim.master import MasterState, RunResult
from ..interrupt import StopFlag, stop_on_signals
from ..outputs import file_stem
from ..scenario import Scenario
from . import phases
from .checkpoint import CHECKPOINT_DIR, RunCheckpoint, Saver
from .fmus import fleet_layout, record_stride
from .setup import (
    Method,
    Predictions,
    RunSetup,
    method_list,
    stats_context,
    window_dependent,
)
from .statistics import MAX_CHUNK_STEPS, RunRecorder, RunStatistics
from .systems import check_run, make_setup

__all__ = ["NONLINEAR_NOTE", "common_window", "simulate"]

#: the prediction of a fleet of nonlinear vehicles is the linear design model's
NONLINEAR_NOTE = ("predicted on the linear design model: the vehicles are nonlinear (the "
                  "6-DOF REMUS 100, docs/remus100-6dof.md, or a vehicle FMU of your own, "
                  "identified: docs/scenarios.md), so simulation and prediction differ by "
                  "what the design model leaves out")


def simulate(sc: Scenario, modes: Sequence[str] | None, seeds: Sequence[int], out_dir: Path | str,
             *, progress: bool = True, log: Callable[[str], None] = print,
             trackings: Sequence[str] | None = None,
             record_hz: float | None = None, record: Sequence[str] | None = None,
             workers: int | None = None, architectures: Sequence[str] | None = None,
             predict: str = "stationary", master: str = "auto",
             window_from_step: int = 0, checkpoint_every: float | None = None,
             resume: RunCheckpoint | None = None,
             realtime: float | None = None, live: str | None = None) -> dict[str, Any]:
    """Co-simulate each method (estimator ``modes`` x tracking laws ``trackings`` x
    ``architectures``, each default the scenario's) on each seed; write
    ``<out>/<scenario>.rrd`` and summary.json.

    The .rrd holds the traces of the first seed of every method (same noise for all
    methods); the summary holds statistics over all seeds, the predictions (Lyapunov
    equation of the sampled closed loop plus, for a planned leader path, its mean motion)
    and the steady-state tracking error of each method. Every method's statistics are
    over one common window [t0, T), t0 the latest of the methods' own window starts
    (:func:`common_window`): the methods are compared on the same samples; the summary's
    ``stats_window_s`` is that window and each method's ``window_start_s`` its t0. The
    .rrd is written by a child process (:mod:`orchestrator.recording.background`) that
    imports Rerun meanwhile.

    Parameters
    ----------
    sc : Scenario
        Any scenario: its deployment, links, vehicle models and FMU kind
        (:func:`orchestrator.running.systems.make_setup`).
    modes : sequence of str or None
        Estimator modes (None: the scenario's).
    seeds : sequence of int
        Noise seeds; every method sees the same noise for a seed.
    out_dir : Path or str
        Output folder (created).
    progress : bool
        Show a progress bar (after one second), only when standard error is a terminal
        (redirected output gets the per-run lines only, no carriage returns).
    log : callable
        Receives one line per run.
    trackings : sequence of str, optional
        Tracking laws (None: the scenario's).
    architectures : sequence of str, optional
        Information architectures of a per-vehicle fleet (None: the scenario's).
    record_hz : float, optional
        Recording rate of fleets, Hz (:func:`orchestrator.running.fmus.record_stride`).
    record : sequence of str, optional
        The groups of outputs the .rrd holds (None: all;
        :mod:`orchestrator.recording.selection`); the statistics use every output.
    workers : int, optional
        Worker processes for the seeds after each method's first (default one per core;
        1: all in this process; :mod:`orchestrator.running.seeds`); results do not
        depend on it.
    predict : str, optional
        "stationary" (default) or "full": also the searches that take minutes (the links'
        critical loss).
    master : str, optional
        auto (default), native or python (:func:`orchestrator.cosim.master.run_system`);
        the summary's ``master`` says which ran each method.
    window_from_step : int, optional
        The statistics window starts at this sample or later (``compare --what plants``:
        the common window of the plants, each a run of its own).
    checkpoint_every : float, optional
        Write a checkpoint of the run in this process every so many wall-clock seconds
        (:mod:`orchestrator.running.checkpoint`; None or 0: none).
    resume : RunCheckpoint, optional
        Go on from this checkpoint: its method and seed resume at its step.
    realtime : float, optional
        Pace the runs in this process to the wall clock, ``realtime`` simulated seconds per
        second (:mod:`orchestrator.cosim.pacing`); the summary's ``realtime`` reports the
        overruns.
    live : str, optional
        A Rerun viewer's URL (``rerun+http://HOST:PORT/proxy``): the .rrd's rows go to it as
        they are written, its layout first (:mod:`orchestrator.recording.live`); with
        ``realtime``, in chunks of about 0.2 s of wall clock. Checked before anything runs.

    Returns
    -------
    dict
        The summary also written to ``summary.json``.
    """
    from ..recording.background import BackgroundWriter
    from .seeds import seed_pool

    t0 = time.perf_counter()
    phases.reset()
    if live is not None:                    # a viewer that is not there: before anything
        from ..recording.live import check_viewer
        check_viewer(live)
    methods = method_list(sc, modes, trackings, architectures)
    out = Path(out_dir)
    setup = make_setup(sc, out / "fmus", methods, predict=predict, master=master)
    check_run(sc, methods, predict=predict, setup=setup,   # run's checks: every caller
              record_hz=record_hz, record=record)
    out.mkdir(parents=True, exist_ok=True)
    # the .rrd writer imports Rerun in a child while we simulate; SIGINT / SIGTERM stop
    # the runs between steps and keep what was simulated
    with BackgroundWriter.take() as writer, stop_on_signals() as stop, \
            seed_pool(sc.steps, len(seeds), len(methods), workers) as pool:
        options = {"modes": modes, "seeds": list(seeds), "trackings": trackings,
                   "record_hz": record_hz, "record": record, "architectures": architectures,
                   "predict": predict, "master": master, "window_from_step": window_from_step}
        keeper = _Keeper(out, checkpoint_every, options, resume, realtime)
        return _simulate(setup, methods, seeds, out, writer, t0, progress=progress, log=log,
                         record_hz=record_hz, record=record, stop=stop, pool=pool,
                         window_from_step=window_from_step, keeper=keeper, live=live)


class _Keeper:
    """The checkpoints of a command's runs in this process, and the one it resumes
    (:mod:`orchestrator.running.checkpoint`)."""

    def __init__(self, out: Path, every_s: float | None, options: dict[str, Any],
                 resume: RunCheckpoint | None, realtime: float | None = None):
        self.out, self.every_s, self.options, self.resume = out, every_s, options, resume
        self.realtime = realtime                #: the pace of the runs (None: as fast as can)
        self.stream: Any = None                 #: the command's .rrd stream
        self.paced: list[dict[str, Any]] = []   #: each paced run's report
        self.written = 0                        #: checkpoints written
        self.seconds = 0.0                      #: spent writing them
        self.resumed_at: float | None = None    #: the time the resumed run went on from, s
        self.before = 0.0                       #: loop seconds of the resumed run before
        self.going_on = False                   #: the run prepared is the resumed one

    def recording(self) -> tuple[bytes, Path] | None:
        """The .rrd stream's state to go on from, and the folder of its segments (None:
        a new recording)."""
        ck = self.resume
        if ck is None or ck.recording is None:
            return None
        return ck.recording, self.out / CHECKPOINT_DIR

    def prepare(self, sc: Scenario, name: str, seed: int, recorder: RunRecorder
                ) -> tuple[RunRecorder, MasterState | None, Saver | None]:
        """The recorder, the master state to start from and the saver of one run (a
        resumed recorder sends to the command's .rrd stream)."""
        start = None
        self.going_on = False
        ck = self.resume
        if ck is not None and ck.method == name and ck.seed == seed:
            recorder, start = ck.recorder, ck.master
            recorder.stream = self.stream
            self.going_on = True
            self.resumed_at, self.before = start.step * sc.h, ck.loop_s
            self.resume = None
        if not self.every_s:
            return recorder, start, None
        t_run = time.perf_counter()
        before = self.before if start is not None else 0.0

        def make(state: MasterState) -> RunCheckpoint:
            recording = (None if self.stream is None else
                         self.stream.checkpoint(self.out / CHECKPOINT_DIR))
            return RunCheckpoint(sc, self.options, name, seed, state, recorder,
                                 before + time.perf_counter() - t_run, recording)
        return recorder, start, Saver(self.out, self.every_s, make)

    def done(self, res: RunResult, saver: Saver | None) -> None:
        """Count what ``saver`` wrote; a resumed run's loop seconds include those before."""
        if saver is not None:
            self.written += saver.count
            self.seconds += saver.seconds
        if "realtime" in res.info:
            self.paced.append(res.info["realtime"])
        if self.going_on:                       # the run that went on from the checkpoint
            res.info["resumed_from_s"] = self.resumed_at
            res.loop_s += self.before
            self.going_on = False

    def summary(self) -> dict[str, Any]:
        """summary.json's ``checkpoints``."""
        return {"every_s": self.every_s or None, "written": self.written,
                "seconds": self.seconds, "resumed_from_s": self.resumed_at}

    def realtime_summary(self) -> dict[str, Any] | None:
        """summary.json's ``realtime``: the factor, the overruns (steps that ended after
        their wall-clock deadline) and the worst lateness over the paced runs, their
        wall-clock and planned seconds; None when not paced."""
        if not self.paced:
            return None
        return {"factor": self.realtime, "runs": len(self.paced),
                "overruns": sum(p["overruns"] for p in self.paced),
                "worst_lateness_s": max(p["worst_lateness_s"] for p in self.paced),
                "wall_s": sum(p["wall_s"] for p in self.paced),
                "planned_s": sum(p["planned_s"] for p in self.paced)}


def _bar(sc: Scenario, runs: int, progress: bool) -> Any:
    if not (progress and sys.stderr.isatty()):
        return None
    from tqdm import tqdm
    return tqdm(total=runs * sc.steps, unit="step", delay=1.0, leave=False, unit_scale=True)


def common_window(predictions: Iterable[Predictions], at_least: int = 0) -> int:
    """First sample of the statistics window every method of a compare shares: the latest
    of the methods' own first samples (each from its settling time,
    :func:`orchestrator.analysis.summary.stats_window`), and ``at_least`` or later.

    Parameters
    ----------
    predictions : iterable of Predictions
        Those of the methods that run.
    at_least : int, optional
        The earliest first sample allowed.

    Returns
    -------
    int
        k0: the window is [k0 h, T).
    """
    return max([int(at_least), *(p.k0 for p in predictions)])


def _predictions(setup: RunSetup, methods: list[Method], results: dict[str, Any],
                 log: Callable[[str], None]) -> tuple[dict[str, Predictions], list[ModelError]]:
    """Every method's predictions, before the first run (their windows give the common
    one); a method impossible for the scenario is skipped, in ``results`` and the log
    (raised when it is the only one)."""
    preds: dict[str, Predictions] = {}
    skipped: list[ModelError] = []
    for method in methods:
        try:
            preds[method.name] = setup.predictions(method)
        except ModelError as exc:       # impossible for this scenario: run the others
            if len(methods) == 1:
                raise
            skipped.append(exc)
            results[method.name] = {"skipped": str(exc), "estimator": method.estimator,
                                    "tracking": method.tracking,
                                    "architecture": method.architecture,
                                    "seeds_completed": 0}
            log(f"{method.name:>9s}: skipped: {exc}")
    return preds, skipped


def _simulate(setup: RunSetup, methods: list[Method], seeds: Sequence[int], out: Path,
              writer: Any, t0: float, *, progress: bool, log: Callable[[str], None],
              record_hz: float | None, stop: StopFlag, pool: Any = None,
              record: Sequence[str] | None = None,
              window_from_step: int = 0, keeper: _Keeper | None = None,
              live: str | None = None) -> dict[str, Any]:
    sc = setup.sc
    keeper = keeper or _Keeper(out, None, {}, None)
    for m in methods:
        setup.fmus(m)                       # every FMU in place before the first step
    results: dict[str, Any] = {}
    streamed: dict[str, int] = {}           # method -> steps its first seed sent to the .rrd
    loop_us: list[float] = []
    masters: dict[str, str] = {}            # method -> the master that ran it here
    bar = _bar(sc, len(methods) * len(seeds), progress)
    if bar is not None:
        log = bar.write
    setup.log = log
    formation = stats_context(sc)
    preds, skipped = _predictions(setup, methods, results, log)
    if len(skipped) == len(methods):
        raise ModelError(f"no method can run on this scenario: {skipped[0]}")
    # one window for all: the methods are compared on the same samples, and predicted over
    # them (a method whose own window starts earlier gets its window predictions again)
    k0 = common_window(preds.values(), window_from_step)
    window = (k0 * sc.h, sc.T)
    preds = {m.name: setup.predictions(m, k0) for m in methods if m.name in preds}
    # the .rrd is written as the runs go: the first seed of every method, chunk by chunk
    rrd_path = out / f"{file_stem(sc.name)}.rrd"
    stride = record_stride(sc, record_hz)
    live_chunk, live_kw = None, {}
    if live is not None:                    # watched live and paced: rows 5 times a second
        live_kw["live"] = live
        if keeper.realtime is not None:
            from ..recording.live import live_chunk_steps
            live_chunk = live_chunk_steps(sc.h, keeper.realtime, MAX_CHUNK_STEPS)
            live_kw["chunk_rows"] = 1       # each chunk written as it comes
    stream = writer.stream(rrd_path, list(preds), sc.h, resume=keeper.recording(),
                           recording_name=f"{sc.name} ({', '.join(preds)})",
                           fleet=fleet_layout(sc), stride=stride, record=record, **live_kw)
    keeper.stream = stream
    bound: dict[int, float | None] = {}     # the full-information bound over the window
    notes: set[str] = set()
    settling = 0.0              # the slowest settling time of a method whose window is early
    for method in methods:
        name = method.name
        if name not in preds:
            continue
        pred = preds[name]
        note = stationarity_note(sc.T, window[0], pred.stationary.settling_time)
        if note is not None:
            notes.add(note)
            settling = max(settling, pred.stationary.settling_time)
        per_seed, link_ages = [], []
        # the seeds after the first on local worker processes (orchestrator.running.seeds)
        pooled = {s: pool.submit(setup, method, s, setup.system(method, s), k0, formation)
                  for s in seeds[1:]} if pool else {}
        predicted = pred.window.cost_rate
        for seed in seeds:
            if stop:
                break
            if seed in pooled:
                stats, loop_s, ages = pooled[seed].result()
                if bar is not None:
                    bar.update(sc.steps)
                loop_us.append(loop_s / sc.steps * 1e6)
                per_seed.append(stats)
                if ages:
                    link_ages.append(ages)
                log(f"{name:>9s} seed {seed}: cost rate {stats['cost_rate']:.4g} (worker "
                    f"process), {loop_s:.2f} s")
                continue
            first = name not in streamed
            recorder = RunRecorder(RunStatistics(sc, k0, formation),
                                   stream=stream if first else None, name=name,
                                   chunk=live_chunk if first else None)
            recorder, start, saver = keeper.prepare(sc, name, seed, recorder)
            res = setup.run(method, seed, progress=bar, stop=stop, recorder=recorder,
                            start=start, checkpoints=saver, realtime=keeper.realtime)
            keeper.done(res, saver)
            masters[name] = res.info["master"]
            if first:
                streamed[name] = res.steps
            if res.info["interrupted_by"]:
                reached = res.steps * sc.h
                log(f"{name:>9s} seed {seed}: interrupted by {res.info['interrupted_by']} at "
                    f"t = {reached:.6g} s (not in the statistics)")
                break
            loop_us.append(res.loop_s / sc.steps * 1e6)
            with phases.phase("statistics"):
                per_seed.append(recorder.statistics.result())
            if "links" in res.info:
                link_ages.append(recorder.statistics.link_ages(res.info["links"]))
            log(f"{name:>9s} seed {seed}: cost rate {per_seed[-1]['cost_rate']:.4g}"
                + ("" if predicted is None else f" (predicted {predicted:.4g})")
                + f", {res.loop_s:.2f} s")
        entry = results[name] = (method_summary(per_seed, pred.window) if per_seed else
                                 {"note": "no seed completed before the interruption"})
        if per_seed and formation is not None:
            entry.update(formation_summary([st["formation"] for st in per_seed],
                                           list(seeds[:len(per_seed)])))
            entry.update(segment_summary([st["segments"] for st in per_seed]))
        entry.update(setup.method_entries(method, link_ages))
        if per_seed and pred.window_from_start is not None:
            entry["cost_rate"]["predicted_window"] = pred.window_from_start.cost_rate
            entry["rms_e"]["predicted_window"] = pred.window_from_start.rms_e
        if per_seed and sc.nonlinear_vehicles and pred.window.cost_rate is not None:
            entry["prediction_note"] = "; ".join(filter(None, [
                entry.get("prediction_note"), NONLINEAR_NOTE]))
        entry.update(estimator=method.estimator, tracking=method.tracking,
                     architecture=method.architecture)
        #: the sampled closed loop's stability margin: largest |eigenvalue| of its error part
        entry["spectral_radius"] = pred.stationary.spectral_radius
        if per_seed and sc.fleet is not None:
            if k0 not in bound:                 # one for the window, not one per method
                with phases.phase("predictions"):
                    bound[k0] = fleet_bound(sc, k0)
            entry["cost_rate_full_information"] = bound[k0]
        entry["window_start_s"] = window[0]
        if window_dependent(pred):
            #: the window of its window predictions: the common one
            entry["prediction_window_s"] = [pred.k0 * sc.h, sc.T]
        entry["seeds_completed"] = len(per_seed)
        if stop:
            break
    if bar is not None:
        bar.close()
    results = {m.name: results[m.name] for m in methods if m.name in results}  # their order
    # an interrupted compare: the .rrd holds each method as far as it ran
    recorded = min(streamed.values(), default=0)
    rrd_info = {"bytes": 0, "signals": 0, "rrd_s": 0.0}
    if recorded:
        with phases.phase("recording"):
            rrd_info = stream.close()
    else:
        stream.abort()
    design = setup.design()
    summary = {
        "scenario": sc.name,
        "source": sc.source,
        "h": sc.h,
        "T": sc.T,
        "steps": sc.steps,
        "seeds": [int(s) for s in seeds],
        "noise_convention": sc.system.noise_convention,
        "noise_stream": NOISE_STREAM,
        "consensus": None if sc.fleet is None else sc.fleet.consensus,
        "deployment": sc.deployment,
        "fmu_kind": sc.fmus,
        "master": masters,
        **fleet_comparison(sc, results),
        "stats_window_s": list(window),
        "stationary": not notes,
        "stationarity_note": "; ".join(sorted(notes)) or None,
        # the figures of the note: 5 tau of the slowest mode, the T for stationary figures
        "settling_time_s": settling if notes else None,
        "stationary_T_s": stationary_horizon(settling) if notes else None,
        "methods": results,
        "design": _design_entry(sc, design),
        "interrupted": bool(stop),
        "interrupted_by": stop.name,
        "time_reached_s": recorded * sc.h if stop else sc.T,
        "rrd": {"path": str(rrd_path) if recorded else None, "traces_of_seed": int(seeds[0]),
                "recorded_every_steps": stride, "recorded_steps": recorded,
                **rrd_info},
        "timing": {"cosim_loop_us_per_step_mean": float(np.mean(loop_us)) if loop_us else None,
                   # where the command's time went (orchestrator.running.phases)
                   "phases_s": phases.split(time.perf_counter() - t0)},
        "fmus": _fmu_entries(setup, methods),
        "checkpoints": keeper.summary(),
        "realtime": keeper.realtime_summary(),
        "wall_s": time.perf_counter() - t0,
        "versions": versions(),
    }
    write_text_atomically(out / "summary.json", json.dumps(summary, indent=2))
    return summary


def _design_entry(sc: Scenario, design: Any) -> dict[str, Any] | None:
    """summary.json's ``design``: the stacked design's poles and residuals (and gains of a
    single system), and what [design] chose (``R``, ``bandwidth``, ``force_3sigma``,
    ``u_max``, ``path_findings``, ...: orchestrator.analysis.weight_search)."""
    out = None if design is None else {
        "closed_loop_poles": [[float(z.real), float(z.imag)] for z in design.closed_loop_poles],
        "residuals": design.residuals,
        **({} if sc.fleet is not None else
           {"Kx": design.Kx.tolist(), "Kz": design.Kz.tolist(), "Kw": design.Kw.tolist()}),
    }
    if sc.design is not None:
        out = {**(out or {}), **sc.design.summary()}
    return out


def _fmu_entries(setup: RunSetup, methods: list[Method]) -> dict[str, dict[str, Any]]:
    """summary.json's ``fmus``: per FMU key its path, size and kind ("python" or
    "native"); a key whose FMU differs between methods (each architecture's network FMU,
    each method's native FMUs) once per method, as ``"<key> (<method>)"``."""
    out: dict[str, dict[str, Any]] = {}
    for m in methods:
        for k, entry in setup.fmu_report(m).items():
            if k in out and out[k]["path"] != entry["path"]:
                k = f"{k} ({m.name})"
            out.setdefault(k, entry)
    return out
