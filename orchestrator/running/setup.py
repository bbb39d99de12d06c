"""The one run step: a :class:`RunSetup` built once from a resolved scenario, and its
:meth:`RunSetup.run` of one (method, seed).

A setup owns everything that differs between the systems a scenario can describe: which
FMUs (pythonfmu, or native where a component has a linear form: ``[simulation] fmus``),
the system description of a method and seed, the predictions of a method, how the traces
map to the stacked layout, and what the summary adds (the acoustic links' figures). The
branch on the deployment is :func:`orchestrator.running.systems.make_setup` (the registry
of deployments); :class:`orchestrator.running.stacked.StackedSetup` is the paper's loop of
three FMUs, :class:`orchestrator.running.per_vehicle.PerVehicleSetup` one vehicle,
estimator and controller FMU per AUV, with or without acoustic links, linear or nonlinear
vehicles. ``run``, ``compare`` (every ``--what``), the seed workers, ``campaign``'s FMU
engine, ``envelope``, the benchmarks and the cross-check all run through it.
"""
from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..analysis.prediction import Prediction
from ..cosim.master import RunResult, run_system
from ..cosim.system import SystemDescription
from ..interrupt import interruptible, mark_simulated
from ..outputs import file_stem
from ..scenario import Scenario, ScenarioError
from ..scenario.loader import check_deployment
from .phases import add as add_phase
from .phases import phase
from .statistics import RunRecorder, RunStatistics, chunk_steps

__all__ = ["NO_PREDICTION", "PREDICT_LEVELS", "Method", "Predictions", "RunSetup", "check_setup",
           "method_list", "run_statistics", "stats_context"]

#: how much a run predicts: nothing (every predicted figure null, with a note), the
#: stationary and window predictions of every method (seconds), or also the searches (the
#: critical loss of links: seconds for formation-4)
PREDICT_LEVELS = ("none", "stationary", "full")
#: the note of every prediction with ``--predict none``
NO_PREDICTION = "no prediction: --predict none asked for none"
#: predictions computed in this process, by what they depend on (RunSetup.predictions)
_PREDICTIONS: dict[tuple, Predictions] = {}


@dataclass(frozen=True)
class Method:
    """One method a run compares: its name and the estimator mode, tracking law and
    information architecture it runs."""

    name: str
    estimator: str
    tracking: str
    architecture: str

    @classmethod
    def of(cls, sc: Scenario) -> Method:
        """The scenario's own method, named after its estimator."""
        return cls(sc.estimator, sc.estimator, sc.tracking, sc.architecture)


def method_list(sc: Scenario, estimators: Sequence[str] | None = None,
                trackings: Sequence[str] | None = None,
                architectures: Sequence[str] | None = None) -> list[Method]:
    """The methods to run: every architecture x estimator x tracking law; names are the
    estimator when only estimators vary, the tracking law when only the law varies, the
    architecture when only it varies, else the varying ones joined by '-'.

    Parameters
    ----------
    sc : Scenario
        Gives the defaults (its estimator, tracking law and architecture).
    estimators, trackings, architectures : sequence of str, optional
        Estimator modes, tracking laws and information architectures to combine.

    Returns
    -------
    list[Method]
    """
    est = list(estimators or [sc.estimator])
    trk = list(trackings or [sc.tracking])
    arc = list(architectures or [sc.architecture])
    out = []
    for a in arc:
        for e in est:
            for t in trk:
                parts = [x for x, many in ((a, len(arc) > 1), (e, len(est) > 1),
                                           (t, len(trk) > 1)) if many]
                out.append(Method("-".join(parts) or e, e, t, a))
    return out


@dataclass(frozen=True)
class Predictions:
    """What the summary predicts for one method."""

    stationary: Prediction                 #: the stationary loop (margin, settling time)
    window: Prediction                     #: over the statistics window (the "predicted")
    window_from_start: Prediction | None   #: the window average from the known start
    k0: int                                #: first sample of the statistics window

    @classmethod
    def of(cls, parts: tuple[Prediction, Prediction, Prediction | None, int]) -> Predictions:
        """From the (stationary, window, from start, k0) the analysis functions return."""
        return cls(*parts)


def window_dependent(pred: Predictions) -> bool:
    """Whether ``pred`` has figures that depend on its window (the mean motion of a planned
    path over it, the average from the known start), beside the stationary ones."""
    return ((pred.window is not pred.stationary and pred.window.cost_rate is not None)
            or (pred.window_from_start is not None
                and pred.window_from_start.cost_rate is not None))


class RunSetup:
    """The FMUs, systems and predictions of one scenario's runs (module docstring).

    Parameters
    ----------
    sc : Scenario
        The resolved scenario (its ``fmus`` chooses pythonfmu or native FMUs).
    fmu_dir : Path
        Where the FMUs go (each method's native FMUs, and each architecture's per-vehicle
        FMUs when several run, in a subfolder of their own).
    methods : sequence of Method, optional
        The methods that will run (default: the scenario's own).
    coupling : str, optional
        The master's coupling, 'gauss-seidel' or 'jacobi'.
    predict : str, optional
        One of :data:`PREDICT_LEVELS`.
    """

    deployment = ""
    #: the master that runs the systems: auto, native or python
    #: (:func:`orchestrator.cosim.master.run_system`; :func:`make_setup` sets it)
    master = "auto"

    def __init__(self, sc: Scenario, fmu_dir: Path | str, methods: Sequence[Method] = (),
                 *, coupling: str = "gauss-seidel", predict: str = "stationary"):
        self.sc = sc
        self.fmu_dir = Path(fmu_dir)
        self.methods = tuple(methods) or (Method.of(sc),)
        self.coupling = coupling
        if predict not in PREDICT_LEVELS:
            raise ValueError(f"predict {predict!r} is not one of {', '.join(PREDICT_LEVELS)}")
        self.predict = predict
        #: told in one line before a step that may take more than about 2 s (None: quiet)
        self.log: Callable[[str], None] | None = None
        self._native: dict[Method, Any] = {}
        self._predictions: dict[Method, Predictions] = {}
        self._windowed: dict[tuple[Method, int], Predictions] = {}   #: over another window

    # what a deployment defines ---------------------------------------------------------
    def python_fmus(self, method: Method) -> dict[str, Path]:
        """The pythonfmu FMUs ``method`` runs (built on first use): FMU key -> path."""
        raise NotImplementedError

    def python_system(self, method: Method, seed: int) -> SystemDescription:
        """The system of ``method`` and ``seed`` on the pythonfmu FMUs."""
        raise NotImplementedError

    def _predict(self, method: Method, k0: int | None = None) -> Predictions:
        """The predictions of ``method``, the window ones over [k0 h, T) (None: the
        method's own window, from its settling time)."""
        raise NotImplementedError

    def stacked(self, system: SystemDescription, traces: dict[str, Any],
                info: dict[str, Any]) -> dict[str, Any]:
        """The traces of a run of ``system`` in the stacked layout (``e``, ``u``, ``x``, ...)."""
        return traces

    def method_entries(self, method: Method, runs: list[Any]) -> dict[str, Any]:
        """What the summary adds for ``method`` beyond the statistics (links' figures)."""
        return {}

    def design(self) -> Any:
        """The stacked tracking design of the first method that uses one, or None."""
        return None

    def prepare(self, method: Method) -> None:
        """Solve what the FMUs of ``method`` would solve in their initialization (kept in
        this process's design cache, :mod:`plant_model.memo`), where a stop can cut it
        short (:meth:`interruptible`); nothing by default."""

    def phase(self, method: Method) -> str:
        """What computing ``method``'s predictions is, for messages."""
        return f"the predictions of {method.name}"

    def interruptible(self, phase: str) -> AbstractContextManager[None]:
        """:func:`orchestrator.interrupt.interruptible`: a stop cuts ``phase`` short until
        a loop has run in this process (then it waits for the loop, which keeps what ran)."""
        return interruptible(phase)

    def announce(self, text: str, seconds: float) -> None:
        """Tell :attr:`log` in one line that a step of about ``seconds`` starts, when it
        may take longer than :data:`orchestrator.running.memory.ANNOUNCE_S`."""
        from .memory import ANNOUNCE_S
        if self.log is not None and seconds > ANNOUNCE_S:
            self.log(text)

    # the same for every deployment ---------------------------------------------------------
    def predictions(self, method: Method, k0: int | None = None) -> Predictions:
        """The predictions of ``method`` (computed once); with ``k0`` (a compare's common
        window [k0 h, T)) its window predictions over that window, the rest unchanged
        (computed once per window, and only when they depend on it).

        Raises
        ------
        ModelError
            If the estimator or the design does not exist or the loop is unstable (named).
        Interrupted
            On SIGINT / SIGTERM while computing them, before any loop ran
            (:func:`orchestrator.interrupt.interruptible`).
        """
        with phase("predictions"):
            return self._predictions_of(method, k0)

    def _predictions_of(self, method: Method, k0: int | None) -> Predictions:
        """:meth:`predictions`, inside its phase."""
        if method not in self._predictions and self.predict == "none":
            from ..analysis.summary import stats_window
            none = Prediction(rms_e=None, rms_u=None, cost_rate=None, spectral_radius=None,
                              settling_time=math.inf, reason=NO_PREDICTION)
            self._predictions[method] = Predictions(none, none, none,
                                                    stats_window(self.sc.T, self.sc.h, math.inf))
        if method not in self._predictions:
            from ..scenario.fingerprint import scenario_digest
            # what they depend on: the scenario but its seed and FMU kind, the method, the
            # coupling (a second run of the same system in this process does not redo them)
            key = (scenario_digest(self.sc, without=("fmus",)), method.estimator,
                   method.tracking, method.architecture, self.coupling)
            if key not in _PREDICTIONS:
                with self.interruptible(self.phase(method)):
                    _PREDICTIONS[key] = self._predict(method)
                while len(_PREDICTIONS) > 64:
                    _PREDICTIONS.pop(next(iter(_PREDICTIONS)))
            self._predictions[method] = _PREDICTIONS[key]
        own = self._predictions[method]
        if k0 is None or k0 == own.k0 or not window_dependent(own):
            return own
        key = (method, int(k0))
        if key not in self._windowed:
            with self.interruptible(self.phase(method)):
                self._windowed[key] = self._predict(method, int(k0))
        return self._windowed[key]

    def _native_system(self, method: Method) -> Any:
        """The method's system with native FMUs where a component has a linear form."""
        if method not in self._native:
            from ..cosim.native import native_system
            folder = self.fmu_dir / "native"
            if len(self.methods) > 1:
                folder = folder / file_stem(method.name)
            system = self.python_system(method, self.sc.seed)
            self._native[method] = native_system(system, self.python_fmus(method), folder)
        return self._native[method]

    def fmus(self, method: Method) -> dict[str, Path]:
        """The FMUs ``method`` runs: FMU key -> path (native ones where ``fmus = native``)."""
        with phase("build"):
            if self.sc.fmus == "native":
                return self._native_system(method).fmus
            return self.python_fmus(method)

    def system(self, method: Method, seed: int) -> SystemDescription:
        """The system ``method`` runs on ``seed`` (on the FMUs of :meth:`fmus`)."""
        python = self.python_system(method, seed)
        if self.sc.fmus != "native":
            return python
        ns = self._native_system(method)
        # the native system was made for the scenario's seed: each noisy native component
        # takes this seed's value, as its pythonfmu counterpart does
        seeds = {c.name: c.parameters["seed"] for c in python.components
                 if "seed" in c.parameters}
        # a component not replaced by a native form (a C model of its own: guidance,
        # network, the REMUS 100; or a pythonfmu FMU kept) has the pythonfmu component's
        # variables: its parameters are this seed's python ones (a link's loss stream and a
        # vehicle's sensors are keyed by the seed)
        same = {c.name: c for c in python.components}
        comps = tuple(same[c.name] if c.name not in ns.replaced
                      else dataclasses.replace(c, parameters={**c.parameters,
                                                              "seed": seeds[c.name]})
                      if c.name in seeds and c.name in ns.forms and ns.forms[c.name].nxi > 0
                      else c for c in ns.system.components)
        return dataclasses.replace(ns.system, components=comps)

    def fmu_report(self, method: Method) -> dict[str, dict[str, Any]]:
        """Per FMU key of ``method``: its path, size and which kind ran ("python" for a
        pythonfmu slave, "native" for compiled code: ours, or a user's vehicle FMU that
        needs no Python), and ``user`` true for a user's own FMU."""
        from fmpy import read_model_description

        from ..cosim.build import FMU_KINDS
        from ..cosim.native_master import is_native_fmu
        ns = self._native_system(method) if self.sc.fmus == "native" else None
        native = set() if ns is None else ns.native_keys

        def kind(k: str, p: Path) -> str:
            if k in FMU_KINDS and FMU_KINDS[k].external:
                return "native" if is_native_fmu(read_model_description(str(p))) else "python"
            return "native" if k in native else "python"
        return {k: {"path": str(p), "bytes": Path(p).stat().st_size, "kind": kind(k, Path(p)),
                    **({"user": True} if k in FMU_KINDS and FMU_KINDS[k].external else {})}
                for k, p in self.fmus(method).items()}

    def run(self, method: Method, seed: int, *, progress: Any = False, stop: Any = None,
            system: SystemDescription | None = None,
            recorder: RunRecorder | None = None, start: Any = None,
            checkpoints: Any = None, realtime: float | None = None) -> RunResult:
        """Co-simulate ``method`` on ``seed`` for the scenario's T; traces in the stacked
        layout, whole, or chunk by chunk to a ``recorder`` as the run goes.

        Parameters
        ----------
        method : Method
        seed : int
            Noise seed.
        progress, stop : Any, optional
            As :func:`orchestrator.cosim.master.run_system`.
        system : SystemDescription, optional
            The system (default :meth:`system`; a worker process gets it made).
        recorder : RunRecorder, optional
            Takes the stacked traces chunk by chunk
            (:class:`orchestrator.running.statistics.RunRecorder`: statistics, the .rrd
            stream, what is kept): the master's buffers hold one chunk
            (:func:`orchestrator.running.statistics.chunk_steps`) whatever T; the result's
            traces are then what the recorder kept.
        start, checkpoints : optional
            With a ``recorder``: resume from a saved
            :class:`~orchestrator.cosim.master.MasterState`, and save one when
            ``checkpoints`` says it is due (:func:`orchestrator.cosim.master.run_system`).
        realtime : float, optional
            Pace the loop to the wall clock (:mod:`orchestrator.cosim.pacing`).

        Returns
        -------
        RunResult

        Raises
        ------
        Interrupted
            On SIGINT / SIGTERM while :meth:`prepare` solves the design, before any loop
            ran in this process.
        """
        t0 = time.perf_counter()
        with phase("build"):
            system = system if system is not None else self.system(method, seed)
        with self.interruptible(self.phase(method)), phase("design"):
            self.prepare(method)
        mark_simulated()
        fmus = self.fmus(method)
        sink, chunk_info = None, {}
        if recorder is not None:
            grid = chunk_steps(system.output_width())
            if recorder.chunk_steps is None:
                recorder.chunk_steps = grid
            if recorder.statistics is not None and recorder.statistics.block is None:
                recorder.statistics.block = grid     # the figures whatever the chunks
            recorder.planned = self.sc.steps
            sink = _StackedSink(self, system, recorder, chunk_info)
        with phase("instantiate"):     # the loop's own seconds are counted apart
            traces, loop_s, info = run_system(system, fmus, self.sc.steps,
                                              coupling=self.coupling, progress=progress,
                                              stop=stop, master=self.master, sink=sink,
                                              instance_suffix=f"_{method.estimator}_{seed}",
                                              start=start, checkpoints=checkpoints,
                                              realtime=realtime)
            add_phase("loop", loop_s - (sink.seconds if sink is not None else 0.0))
            if sink is not None:              # the chunks' stacking and statistics
                add_phase("statistics", sink.seconds)
        if recorder is not None:
            info.update(chunk_info)
            stacked = recorder.traces()
        else:
            with phase("statistics"):
                stacked = self.stacked(system, traces, info)
        return RunResult(mode=method.estimator, seed=int(seed), h=self.sc.h,
                         traces=stacked,
                         wall_s=time.perf_counter() - t0, loop_s=loop_s,
                         coupling=self.coupling, info=info)

    def __getstate__(self) -> dict[str, Any]:
        """What a worker process needs: the scenario and the FMUs built here (the
        predictions and network analyses stay in this process)."""
        state = dict(self.__dict__)
        state["_predictions"] = {}
        state["log"] = None
        return state


class _StackedSink:
    """The master's :class:`~orchestrator.cosim.master.TraceSink` of a run with a recorder:
    each chunk in the stacked layout (:meth:`RunSetup.stacked`) to the recorder; the
    seconds it takes (counted as statistics, not as the loop)."""

    def __init__(self, setup: RunSetup, system: SystemDescription, recorder: RunRecorder,
                 info: dict[str, Any]):
        self.setup, self.system, self.recorder, self.info = setup, system, recorder, info
        self.chunk_steps = recorder.chunk_steps
        self.seconds = 0.0

    def take(self, k0: int, traces: dict[str, Any]) -> None:
        t0 = time.perf_counter()
        stacked = self.setup.stacked(self.system, traces, self.info)
        self.recorder.links = self.info.get("links")
        self.recorder.take(k0, stacked)
        self.seconds += time.perf_counter() - t0


def check_setup(sc: Scenario, coupling: str = "gauss-seidel") -> None:
    """Refuse, in one line naming the combination, what no setup can run.

    Raises
    ------
    ScenarioError
        A [network], [sensors] or nonlinear vehicle without the per-vehicle deployment,
        the distributed law with the classical estimator, or a per-vehicle system with
        the Jacobi coupling.
    """
    check_deployment(sc)
    if sc.deployment == "per-vehicle" and coupling != "gauss-seidel":
        raise ScenarioError(f"{sc.source}: coupling {coupling!r} runs the stacked loop only "
                            "(its prediction is the Jacobi-coupled stacked loop's); the "
                            "per-vehicle deployment runs Gauss-Seidel")


def stats_context(sc: Scenario) -> tuple | None:
    """What :func:`orchestrator.analysis.summary.run_stats` needs beyond Q, R and k0 for a
    fleet: (position_index, offsets, edges, h), or None."""
    from .fmus import fleet_layout
    layout = fleet_layout(sc)
    return (None if layout is None else
            (layout.position_index, layout.offsets, layout.edges, sc.h))


def run_statistics(sc: Scenario, res: RunResult, k0: int,
                   formation: tuple | None) -> dict[str, Any]:
    """The statistics of one run as the summary and the campaign rows hold them, from its
    whole traces (:class:`orchestrator.running.statistics.RunStatistics` in one chunk)."""
    stats = RunStatistics(sc, k0, formation)
    stats.add(0, res.traces)
    return stats.result()
