"""Fixed-step co-simulation master on fmpy, driven by a :class:`SystemDescription`.

Within macro step k (t = k h, never accumulated), ``coupling="gauss-seidel"`` (the
default) reads the components' outputs in the order their declared direct feedthrough
requires (:func:`orchestrator.cosim.system.evaluation_order`) and sets each output on the
inputs it feeds as soon as it is read, then steps every FMU. For the paper's loop that is
the exact discrete-time loop::

    plant -> y[k], ybar[k] (+ truth) -> estimator -> xhat, what, zhat
          -> controller -> u[k] -> plant and estimator -> all three doStep(t, h)

``coupling="jacobi"`` is the same loop with another order of operations, what libcosim's
fixed-step algorithm (Open Simulation Platform) and fmpy's ``simulate_ssp`` do: every input
is set from the outputs read at the previous communication point, all FMUs step, then all
outputs are read::

    set inputs from the outputs read at t_k -> all doStep(t_k, h) -> read outputs (t_k+1)

Row k of a Jacobi trace holds the outputs read at t_k, i.e. the values transferred into
step k. A measurement-to-control path through two feedthrough FMUs gains two steps of
latency this way (see orchestrator/analysis/jacobi.py for its prediction).

The plan is resolved once (:mod:`orchestrator.cosim.plan`): value references, one batched
fmi2GetReal per run of consecutive outputs of a component, one batched fmi2SetReal per run
of consecutive outputs feeding one component; the FMUs read and write the trace arrays in
place (row k of a component's trace is the buffer fmi2GetReal fills and the buffer its
consumers' inputs are set from). A connection that carries nothing in the run (the truth
signals outside mode ``ideal``) is not in the plan.

The trace buffers hold the whole run, or with a :class:`TraceSink` one chunk of steps,
handed to the sink after each chunk and then reused: memory then depends on the chunk, not
on the horizon, and the traces the sink takes are the whole run's bit for bit.

:func:`compile_plan` writes the plan out as a Python loop, the reference;
:mod:`orchestrator.cosim.native_master` runs the same plan in a compiled C loop, to the
same traces bit for bit (``run_system(master=...)``; by default when every FMU is native).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from fmpy import read_model_description

from .checks import connection_problems, fmu_variables
from .instance import CosimError, Extracted, FmuInstance
from .pacing import Pacer
from .plan import StepPlan, compile_plan, initial_reads, plan_steps
from .system import SystemDescription

__all__ = ["COUPLINGS", "Checkpoints", "CosimError", "MasterState", "RunResult", "StepPlan",
           "TraceSink", "chunk_rows",
           "compile_plan", "initial_reads", "plan_steps", "run_system"]

#: how the master couples the FMUs within a step (see the module docstring)
COUPLINGS = ("gauss-seidel", "jacobi")
#: steps the Python master runs between two looks at the stop flag and the progress bar
_SLICE = 200


@dataclass
class RunResult:
    """Traces of one co-simulation (row k = sample k, t = k h), keyed by
    :meth:`SystemDescription.trace_names` (the output's name, e.g. ``y``, ``u``)."""

    mode: str
    seed: int
    h: float
    traces: dict[str, np.ndarray]
    wall_s: float
    loop_s: float
    coupling: str = "gauss-seidel"
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def steps(self) -> int:
        """Number of steps the run simulated (the rows of its traces, when it keeps them
        whole)."""
        if "steps_done" in self.info:
            return int(self.info["steps_done"])
        return next(iter(self.traces.values())).shape[0]

    @property
    def t(self) -> np.ndarray:
        """Sample times t = k h, s."""
        return np.arange(self.steps) * self.h


def _step_loop(plan: StepPlan, k0: int, k1: int, h: float, last: int, bar: Any,
               stop: Any = None, row0: int = 0, pacer: Pacer | None = None) -> int:
    """Run macro steps k0 <= k < k1 of the plan (t = k h; step k on buffer row k - row0)
    in slices ending at multiples of 200 (progress bar, ``stop`` checked between slices;
    with a ``pacer``, one step at a time, each waiting for its wall-clock deadline);
    returns the step reached."""
    run = plan.compiled()
    if pacer is not None:
        pacer.begin(k0)
    a = k0
    while a < k1:                       # slices on the grid of multiples of _SLICE
        if stop:
            return a
        b = min((a // _SLICE + 1) * _SLICE, k1)
        if pacer is None:
            run(a, b, h, last, row0)
        else:
            for k in range(a, b):
                run(k, k + 1, h, last, row0)
                pacer.after(k)
        if bar is not None:
            bar.update(b - a)
        a = b
    return k1


def _with_origin(exc: CosimError, instances: list[FmuInstance]) -> CosimError:
    """``exc``, led by the first FMU (in evaluation order) that logged a non-finite output, if
    the failing FMU logged none: a pythonfmu slave can only log it at fmi2GetReal (pythonfmu
    0.7 answers fmi2OK or fmi2Fatal there), so the refusal may come later, from the FMU that
    received the value; the error then names the output where it went non-finite first."""
    failing = getattr(exc, "label", None)
    if any(f.label == failing and f.nonfinite_output() for f in instances):
        return exc
    for fmu in instances:
        if fmu.label != failing:
            found = fmu.nonfinite_output()
            if found is not None:
                err = CosimError(f"{fmu.label} FMU: {found} (read with fmi2GetReal); then {exc}")
                err.label = fmu.label           # type: ignore[attr-defined]
                return err
    return exc


class TraceSink(Protocol):
    """Takes a run's traces chunk by chunk (:func:`run_system` with ``sink``)."""

    #: steps per chunk (the master's trace buffers hold one chunk: memory ~ chunk x width)
    chunk_steps: int

    def take(self, k0: int, traces: dict[str, np.ndarray]) -> None:
        """Rows k0 .. k0 + n - 1 of the run, keyed as :func:`run_system`'s traces. The
        arrays are views of buffers the next chunk overwrites: copy what is kept."""


@dataclass
class MasterState:
    """Where a run stands between two chunks: what a checkpoint holds of the master, and
    what a resumed run starts from (:func:`run_system` ``start``)."""

    step: int                           #: the next step to run (steps 0 .. step - 1 ran)
    fmus: dict[str, bytes]              #: component -> its FMU's serialized state
    #: Jacobi: component -> its outputs read after step - 1 (what step ``step`` is fed)
    next_row: dict[str, np.ndarray] | None = None


class Checkpoints(Protocol):
    """Asked after every chunk whether to save the run's state (:func:`run_system`)."""

    def due(self, step: int) -> bool:
        """Whether to save now, ``step`` steps done."""

    def save(self, state: MasterState) -> None:
        """Keep ``state`` (write it, atomically)."""


def _split(system: SystemDescription, rec: Mapping[str, np.ndarray],
           rows: int) -> dict[str, np.ndarray]:
    """The first ``rows`` rows of each component's buffer, split into its outputs (keyed by
    :meth:`SystemDescription.trace_names`; views, no copy)."""
    names = system.trace_names()
    traces: dict[str, np.ndarray] = {}
    for comp in system.components:
        i = 0
        for spec in comp.arrays("output"):
            traces[names[(comp.name, spec.name)]] = rec[comp.name][:rows, i:i + spec.size]
            i += spec.size
    return traces


def _run_chunks(loop: Callable[..., int], plan: StepPlan, rec: Mapping[str, np.ndarray],
                steps: int, chunk: int, h: float, bar: Any, stop: Any,
                give: Callable[[int, int], None] | None, start: int = 0,
                saved: Callable[[int], None] | None = None,
                pacer: Pacer | None = None) -> int:
    """Steps start .. steps - 1 in chunks of ``chunk`` steps (the grid k = 0, chunk, 2
    chunk, ...) on buffers of chunk (+ 1) rows: chunk [k0, k1) on rows 0 .. k1 - k0 - 1,
    handed to ``give(k0, rows)``; Jacobi's reads after the chunk's last step (row k1 - k0)
    move to row 0 for the next chunk; then ``saved(k1)`` (a checkpoint, if due). Returns the
    step reached (fewer than ``steps`` when stopped)."""
    k0 = start
    while k0 < steps:
        if stop:
            return k0
        k1 = min((k0 // chunk + 1) * chunk, steps)
        done = loop(plan, k0, k1, h, steps, bar, stop, k0 if give is not None else 0, pacer)
        if give is not None and done > k0:
            give(k0, done - k0)
        if done < k1:
            return done
        if give is not None and plan.after:
            for buf in rec.values():
                buf[0] = buf[k1 - k0]
        if saved is not None and k1 < steps:
            saved(k1)
        k0 = k1
    return steps


def _state(step: int, inst: Mapping[str, FmuInstance], rec: Mapping[str, np.ndarray],
           jacobi: bool) -> MasterState:
    """The run's :class:`MasterState` between chunks, ``step`` steps done."""
    return MasterState(step, {name: fmu.serialized_state() for name, fmu in inst.items()},
                       {name: buf[0].copy() for name, buf in rec.items()} if jacobi else None)


def _restore(start: MasterState, inst: Mapping[str, FmuInstance],
             system: SystemDescription) -> None:
    """Every instance set to its saved state.

    Raises
    ------
    CosimError
        If the saved states are not those of this system's components, or an FMU refuses
        its state.
    """
    if set(start.fmus) != set(inst):
        extra, missing = sorted(set(start.fmus) - set(inst)), sorted(set(inst) - set(start.fmus))
        raise CosimError(f"system {system.name!r}: the saved run's components differ "
                         f"(not in this system: {', '.join(extra) or 'none'}; without a saved "
                         f"state: {', '.join(missing) or 'none'})")
    for name, fmu in inst.items():
        fmu.restore_state(start.fmus[name])


def chunk_rows(sink: TraceSink | None, steps: int) -> int:
    """Steps per chunk: the whole run without a sink, else the sink's (at least 1)."""
    return steps if sink is None else max(1, min(steps, int(sink.chunk_steps)))


def run_system(system: SystemDescription, fmus: Mapping[str, Path], steps: int, *,
               coupling: str = "gauss-seidel", progress: Any = False,
               instance_suffix: str = "", stop: Any = None,
               master: str = "auto", sink: TraceSink | None = None,
               start: MasterState | None = None, checkpoints: Checkpoints | None = None,
               realtime: float | None = None
               ) -> tuple[dict[str, np.ndarray], float, dict[str, Any]]:
    """Co-simulate ``system`` for ``steps`` communication steps of ``system.h``.

    Parameters
    ----------
    system : SystemDescription
        The system to run.
    fmus : Mapping[str, Path]
        FMU key (``Component.fmu``) -> .fmu path.
    steps : int
        Number of communication steps.
    coupling : str, optional
        'gauss-seidel' or 'jacobi' (module docstring).
    progress : Any, optional
        False, True (a progress bar shown after one second) or a shared bar object with
        ``update(n)``.
    instance_suffix : str, optional
        Appended to each component's name to make its FMI instance name.
    stop : StopFlag, optional
        Checked every 200 steps by the Python master, before every step by the compiled
        one (:mod:`orchestrator.interrupt`): once true, the run ends there and keeps the
        steps simulated.
    master : str, optional
        ``python`` (this module's loop, the reference), ``native`` (the same plan in C,
        :mod:`orchestrator.cosim.native_master`) or ``auto`` (native when every component
        is a native FMU and a C compiler is present, else python).
    sink : TraceSink, optional
        Takes the traces chunk by chunk as the run goes (:class:`TraceSink`): the buffers
        then hold one chunk, whatever the horizon; the returned traces are empty. The
        traces it takes are those returned without it, bit for bit.
    start : MasterState, optional
        Resume there (with a ``sink``): every FMU initialized as for a new run, then set to
        its saved state; the sink takes steps ``start.step`` onwards, the same as the
        uninterrupted run's bit for bit (FMUs that serialize their state whole).
    checkpoints : Checkpoints, optional
        Asked after every chunk but the last (with a ``sink``): when due, given the
        :class:`MasterState` there (every FMU's serialized state).
    realtime : float, optional
        Pace the steps to the wall clock, ``realtime`` simulated seconds per second
        (:mod:`orchestrator.cosim.pacing`); ``info["realtime"]`` then reports the overruns.

    Returns
    -------
    traces : dict[str, np.ndarray]
        Keyed by :meth:`SystemDescription.trace_names`, row k = sample k (fewer rows than
        ``steps`` if stopped); empty with a ``sink``.
    loop_s : float
        Seconds spent in the step loop.
    info : dict[str, Any]
        ``order`` (the evaluation order), ``calls_per_step``, ``steps_done``,
        ``interrupted_by`` (the signal's name, or None), ``master`` (``native`` or
        ``python``) and ``master_reason``.

    Raises
    ------
    ValueError
        If the coupling or the master is unknown.
    NativeBuildError
        ``master="native"`` and the compiled master cannot be built.
    CosimError
        If an FMU is missing, the system does not match its FMUs or an FMI call fails.
    """
    if coupling not in COUPLINGS:
        raise ValueError(f"coupling {coupling!r} is not one of {', '.join(COUPLINGS)}")
    if sink is None and (start is not None or checkpoints is not None):
        raise ValueError("resuming or checkpointing a run needs a sink (its chunks)")
    h = float(system.h)
    used = {c.fmu for c in system.components}
    missing = sorted(used - set(fmus))
    if missing:
        raise CosimError(f"system {system.name!r}: no FMU given for {', '.join(missing)}")
    ex = Extracted({k: fmus[k] for k in used})
    inst: dict[str, FmuInstance] = {}
    bar = None
    try:
        mds = {k: read_model_description(str(fmus[k])) for k in used}
        variables = {k: fmu_variables(md) for k, md in mds.items()}    # once per FMU file
        problems = connection_problems(
            {c.name: variables[c.fmu] for c in system.components},
            system.scalar_connections(),
            fmu_names={c.name: Path(fmus[c.fmu]).name for c in system.components})
        if problems:
            raise CosimError(f"system {system.name!r} does not match its FMUs: "
                             + "; ".join(problems))
        from .native_master import choose_master, run_native_loop
        chosen, reason = choose_master(master, {c.name: mds[c.fmu]
                                                for c in system.components})
        for comp in system.components:
            inst[comp.name] = FmuInstance(comp.name, fmus[comp.fmu], ex.dirs[comp.fmu],
                                          f"{comp.name}{instance_suffix}", mds[comp.fmu])
            with np.errstate(over="ignore", invalid="ignore"):      # as in the loop below
                inst[comp.name].initialize(dict(comp.parameters), T=steps * h)
        if start is not None:
            _restore(start, inst, system)
        chunk = chunk_rows(sink, steps)
        pacer = None if realtime is None else Pacer(realtime, h)
        rows = chunk + (1 if sink is not None else 0)       # Jacobi reads one row ahead
        rec = {c.name: np.zeros((rows, sum(s.size for s in c.arrays("output"))))
               for c in system.components}
        plan = plan_steps(system, inst, rec, coupling)
        if progress is True:
            from tqdm import tqdm
            bar = tqdm(total=steps, unit="step", delay=1.0, leave=False)
        elif progress:
            bar = progress                      # a shared bar (an object with update(n))
        t_loop = time.perf_counter()
        try:
            # the slaves run in this thread: numpy's overflow warnings are not printed (the
            # FMU refuses a non-finite output itself, naming it, in one logged line)
            with np.errstate(over="ignore", invalid="ignore"):
                if start is None:
                    initial_reads(plan)
                elif plan.after:                    # Jacobi: what the next step is fed
                    for name, row in (start.next_row or {}).items():
                        rec[name][0] = row
                give = None if sink is None else (
                    lambda k0, n: sink.take(k0, _split(system, rec, n)))
                saved = None if checkpoints is None else (
                    lambda k: checkpoints.save(_state(k, inst, rec, bool(plan.after)))
                    if checkpoints.due(k) else None)
                done = _run_chunks(run_native_loop if chosen == "native" else _step_loop,
                                   plan, rec, steps, chunk, h, bar, stop, give,
                                   0 if start is None else start.step, saved, pacer)
                if pacer is not None:
                    pacer.finish()
        except CosimError as exc:
            first = [o.split(".")[0] for o in plan.order] + list(system.names)
            raise _with_origin(exc, [inst[c] for c in dict.fromkeys(first) if c in inst]) \
                from None
        loop_s = time.perf_counter() - t_loop
    finally:
        if progress is True and bar is not None:
            bar.close()
        for fmu in inst.values():
            fmu.close()
        ex.cleanup()
    traces = {} if sink is not None else _split(system, rec, done)
    more: dict[str, Any] = {}
    calls = [op[7] for op in plan.exchange + plan.after]
    if pacer is not None:
        more["realtime"] = pacer.report(done)
    return traces, loop_s, {**more, "order": plan.order, "steps_done": done,
                            "interrupted_by": getattr(stop, "name", None) if stop else None,
                            "master": chosen, "master_reason": reason,
                            "calls_per_step": calls + [
        f"fmi2DoStep ({who.label})" for *_, who in plan.stepping]}
