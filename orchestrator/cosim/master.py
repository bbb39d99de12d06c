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

The plan is resolved once: value references, one batched fmi2GetReal per run of
consecutive outputs of a component, one batched fmi2SetReal per run of consecutive
outputs feeding one component; the FMUs read and write the trace arrays in place (row k
of a component's trace is the buffer fmi2GetReal fills and the buffer its consumers'
inputs are set from). A connection that carries nothing in the run (the truth signals
outside mode ``ideal``) is not in the plan.

:func:`compile_plan` writes the plan out as a Python loop, the reference;
:mod:`orchestrator.cosim.native_master` runs the same plan in a compiled C loop, to the
same traces bit for bit (``run_system(master=...)``; by default when every FMU is native).
"""
from __future__ import annotations

import ctypes
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from itertools import groupby
from pathlib import Path
from typing import Any

import numpy as np
from fmpy import read_model_description

from .checks import connection_problems, fmu_variables
from .instance import CosimError, Extracted, FmuInstance
from .system import SystemDescription, evaluation_order

__all__ = ["COUPLINGS", "CosimError", "RunResult", "StepPlan", "compile_plan",
           "initial_reads", "plan_steps", "run_system"]

#: how the master couples the FMUs within a step (see the module docstring)
COUPLINGS = ("gauss-seidel", "jacobi")
_DOUBLE = 8


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
        """Number of samples in the traces."""
        return next(iter(self.traces.values())).shape[0]

    @property
    def t(self) -> np.ndarray:
        """Sample times t = k h, s."""
        return np.arange(self.steps) * self.h


@dataclass
class StepPlan:
    """What one macro step does, resolved to raw FMI calls.

    ``exchange``: (function, component pointer, value-reference array address, count,
    buffer address in row 0, row stride, instance, call label, byte offset of that address
    in its row) for the get/set calls
    before the steps; ``stepping``: (fmi2DoStep, component pointer, instance);
    ``after``: get calls after the steps, into the next row (Jacobi only)."""

    exchange: list[tuple]
    stepping: list[tuple]
    after: list[tuple]
    order: list[str]                    #: the evaluation order, for reports
    keep: list[Any] = field(default_factory=list)   #: ctypes arrays the calls point into


def _runs(cols: list[int]) -> list[tuple[int, int]]:
    """Index ranges [a, b) of consecutive runs in the positions of ``cols``."""
    runs, start = [], 0
    for i in range(1, len(cols) + 1):
        if i == len(cols) or cols[i] != cols[i - 1] + 1:
            runs.append((start, i))
            start = i
    return runs


def plan_steps(system: SystemDescription, inst: Mapping[str, FmuInstance],
               rec: Mapping[str, np.ndarray], coupling: str) -> StepPlan:
    """Resolve the system's active connections into batched FMI calls.

    Parameters
    ----------
    system : SystemDescription
        The system.
    inst : Mapping[str, FmuInstance]
        Component name -> its initialized instance.
    rec : Mapping[str, np.ndarray]
        Component name -> trace array (steps, outputs) the calls read and write in place.
    coupling : str
        'gauss-seidel' or 'jacobi' (module docstring).

    Returns
    -------
    StepPlan
        The get / set calls, the steps and the evaluation order.

    Raises
    ------
    CosimError
        If a connection's two ends differ in size.
    AlgebraicLoopError
        If Gauss-Seidel coupling meets an algebraic loop.
    """
    keep: list[Any] = []                # ctypes arrays the plan points into

    def vr_array(fmu: FmuInstance, names: list[str]) -> int:
        arr = fmu.vrs(names)
        keep.append(arr)
        return ctypes.addressof(arr)

    cols: dict[str, dict[str, list[int]]] = {}      # component -> output array -> columns
    names: dict[str, list[str]] = {}                # component -> output scalar names
    for comp in system.components:
        cols[comp.name], names[comp.name], i = {}, [], 0
        for spec in comp.arrays("output"):
            scal = spec.elements
            cols[comp.name][spec.name] = list(range(i, i + len(scal)))
            names[comp.name] += scal
            i += len(scal)

    def get_ops(comp: str, columns: list[int]) -> list[tuple]:
        fmu, buf = inst[comp], rec[comp]
        ops = []
        for a, b in _runs(columns):
            c0 = columns[a]
            ops.append((fmu.get_real, fmu.component,
                        vr_array(fmu, names[comp][c0:c0 + b - a]), b - a,
                        buf.ctypes.data + c0 * _DOUBLE, buf.strides[0], fmu, "fmi2GetReal",
                        c0 * _DOUBLE))
        return ops

    active = system.active_connections()

    def set_ops(source: str, outputs: set[str]) -> list[tuple]:
        """Sets fed by these outputs of ``source``: per target, one call per run of
        connections whose source columns follow each other (an output feeding two inputs
        of one target is two calls, not one per element)."""
        per_target: dict[str, list[list[tuple[int, str, str]]]] = {}
        for c in active:
            if c.source != source or c.output not in outputs:
                continue
            tgt = system.component(c.target)
            dst = tgt.array(c.input).elements
            src_cols = cols[source][c.output]       # sizes match: checked before the plan
            per_target.setdefault(c.target, []).append(
                [(col, name, c.input) for col, name in zip(src_cols, dst)])
        ops = []
        buf = rec[source]
        for target, conns in per_target.items():
            conns.sort(key=lambda items: items[0][0])
            groups: list[list[tuple[int, str, str]]] = []
            for items in conns:
                if groups and groups[-1][-1][0] + 1 == items[0][0]:
                    groups[-1].extend(items)
                else:
                    groups.append(list(items))
            fmu = inst[target]
            for items in groups:
                ins = ", ".join(dict.fromkeys(arr for _, _, arr in items))
                col0 = items[0][0]
                ops.append((fmu.set_real, fmu.component,
                            vr_array(fmu, [n for _, n, _ in items]), len(items),
                            buf.ctypes.data + col0 * _DOUBLE, buf.strides[0], fmu,
                            f"fmi2SetReal ({ins} from {source})", col0 * _DOUBLE))
        return ops

    stepping = [(inst[c].do_step, inst[c].component, inst[c]) for c in system.names]
    if coupling == "gauss-seidel":
        order = evaluation_order(system)
        exchange: list[tuple] = []
        for comp, run in groupby(order, key=lambda n: n[0]):   # consecutive outputs of one
            group = [o for _, o in run]                          # component: one get
            exchange += get_ops(comp, sorted(col for o in group for col in cols[comp][o]))
            exchange += set_ops(comp, set(group))
        plan = StepPlan(exchange, stepping, [], [f"{c}.{o}" for c, o in order], keep)
    else:
        sets = [op for comp in system.names for op in set_ops(comp, set(cols[comp]))]
        gets = [op for comp in system.names for op in get_ops(
            comp, [c for cs in cols[comp].values() for c in cs])]
        plan = StepPlan(sets, stepping, gets, system.names, keep)
    return plan


def compile_plan(plan: StepPlan) -> tuple[Callable[[int, int, float, int], None], str]:
    """The plan as one Python function ``run(k0, k1, h, last)`` stepping k0 <= k < k1.

    Written out call by call (every function, pointer and count a local constant), as a
    hand-written master for this system would be. Per step and call:
    ``st = f(component, value references, count, row address)``; a non-zero status raises
    the instance's CosimError naming the call and the time t = k h (s).

    Parameters
    ----------
    plan : StepPlan
        The resolved plan (:func:`plan_steps`).

    Returns
    -------
    run : Callable
        ``run(k0, k1, h, last)``: steps k0..k1-1 of ``h`` s; ``last`` is the number of
        steps of the run (Jacobi reads no outputs after the last one).
    source : str
        Its source text, for reading and reports.
    """
    env: dict[str, Any] = {}
    lines: list[str] = []

    def const(prefix: str, i: int, value: Any) -> str:
        name = f"{prefix}{i}"
        env[name] = value
        return name

    rows: dict[tuple[int, int], str] = {}      # (row-0 address, stride) -> its variable

    def row_of(base: int, stride: int, col: int) -> str:
        key = (base - col, stride)
        if key not in rows:
            rows[key] = f"r{len(rows)}"
            env[f"b{rows[key]}"], env[f"s{rows[key]}"] = key
        return rows[key]

    def calls(ops: list[tuple], tag: str, row: str, indent: str, when: str) -> None:
        for i, (fn, c, vr, n, base, stride, who, what, col) in enumerate(ops):
            f, cc, v, w, lab = (const(x, f"{tag}{i}", y) for x, y in
                                (("f", fn), ("c", c), ("v", vr), ("w", who), ("l", what)))
            r = row_of(base, stride, col)
            addr = f"{r}{row} + {col}" if col else f"{r}{row}"
            lines.append(f"{indent}st = {f}({cc}, {v}, {n}, {addr})")
            lines.append(f"{indent}if st:")
            lines.append(f"{indent}    raise {w}.fail(f\"{{{lab}}} at t = {{{when}}} s\", st)")

    lines.append("for k in range(k0, k1):")
    lines.append("    t = k * h")
    head = len(lines)
    calls(plan.exchange, "x", "", "    ", "t")
    for i, (fn, c, who) in enumerate(plan.stepping):
        f, cc, w = const("f", f"d{i}", fn), const("c", f"d{i}", c), const("w", f"d{i}", who)
        lines.append(f"    st = {f}({cc}, t, h, 1)")
        lines.append("    if st:")
        lines.append(f"        raise {w}.fail(f\"fmi2DoStep at t = {{t}} s\", st)")
    exchange_rows = list(rows.values())
    if plan.after:
        lines.append("    if k + 1 < last:")
        mark = len(lines)
        calls(plan.after, "a", "_next", "        ", "(k + 1) * h")
        lines[mark:mark] = [f"        {r}_next = b{r} + (k + 1) * s{r}" for r in rows.values()]
    lines[head:head] = [f"    {r} = b{r} + k * s{r}" for r in exchange_rows]
    params = ", ".join(f"{k}={k}" for k in env)
    src = (f"def run(k0, k1, h, last, {params}):\n"
           + "\n".join("    " + ln for ln in lines) + "\n")
    ns: dict[str, Any] = dict(env)
    exec(compile(src, "<auv-cosim step plan>", "exec"), ns)
    return ns["run"], src


def initial_reads(plan: StepPlan) -> None:
    """Jacobi: read the outputs at t = 0 into row 0 (the plan's ``after`` calls).

    Raises
    ------
    CosimError
        If a call fails (named, at t = 0.0 s).
    """
    for fn, c, vr, n, base, _, who, what, _ in plan.after:
        st = fn(c, vr, n, base)
        if st:
            raise who.fail(f"{what} at t = 0.0 s", st)


def _step_loop(plan: StepPlan, steps: int, h: float, bar: Any, stop: Any = None) -> int:
    """Run ``steps`` macro steps of the plan (t = k h) in chunks of 200 (progress bar,
    ``stop`` checked between chunks); returns the number of steps run."""
    run, _ = compile_plan(plan)
    chunk = 200
    for k0 in range(0, steps, chunk):
        if stop:
            return k0
        run(k0, min(k0 + chunk, steps), h, steps)
        if bar is not None:
            bar.update(min(chunk, steps - k0))
    return steps


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


def run_system(system: SystemDescription, fmus: Mapping[str, Path], steps: int, *,
               coupling: str = "gauss-seidel", progress: Any = False,
               instance_suffix: str = "", stop: Any = None,
               master: str = "auto") -> tuple[dict[str, np.ndarray], float, dict[str, Any]]:
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

    Returns
    -------
    traces : dict[str, np.ndarray]
        Keyed by :meth:`SystemDescription.trace_names`, row k = sample k (fewer rows than
        ``steps`` if stopped).
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
        rec = {c.name: np.zeros((steps, sum(s.size for s in c.arrays("output"))))
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
                initial_reads(plan)
                done = (run_native_loop if chosen == "native" else _step_loop)(
                    plan, steps, h, bar, stop)
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
    names = system.trace_names()
    traces: dict[str, np.ndarray] = {}
    for comp in system.components:
        i = 0
        for spec in comp.arrays("output"):
            traces[names[(comp.name, spec.name)]] = rec[comp.name][:done, i:i + spec.size]
            i += spec.size
    calls = [op[7] for op in plan.exchange + plan.after]
    return traces, loop_s, {"order": plan.order, "steps_done": done,
                            "interrupted_by": getattr(stop, "name", None) if stop else None,
                            "master": chosen, "master_reason": reason,
                            "calls_per_step": calls + [
        f"fmi2DoStep ({who.label})" for *_, who in plan.stepping]}
