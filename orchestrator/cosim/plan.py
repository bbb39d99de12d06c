"""The step plan of the master (:mod:`orchestrator.cosim.master`): a system's active
connections resolved once into batched raw FMI calls (:func:`plan_steps`), written out as a
Python loop (:func:`compile_plan`, the reference the compiled master follows call for call).

Value references, one batched fmi2GetReal per run of consecutive outputs of a component,
one batched fmi2SetReal per run of consecutive outputs feeding one component; the FMUs read
and write the trace buffers in place (row k of a component's buffer is the one fmi2GetReal
fills and its consumers' inputs are set from).
"""
from __future__ import annotations

import ctypes
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from itertools import groupby
from typing import Any

import numpy as np

from .instance import FmuInstance
from .system import SystemDescription, evaluation_order

__all__ = ["StepPlan", "compile_plan", "initial_reads", "plan_steps"]

_DOUBLE = 8


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
    _run: Any = field(default=None, repr=False)

    def compiled(self) -> Callable[[int, int, float, int, int], None]:
        """:func:`compile_plan`'s ``run``, compiled once."""
        if self._run is None:
            self._run = compile_plan(self)[0]
        return self._run


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


def compile_plan(plan: StepPlan) -> tuple[Callable[[int, int, float, int, int], None], str]:
    """The plan as one Python function ``run(k0, k1, h, last, row0)`` stepping
    k0 <= k < k1, step k on row k - row0 of the trace buffers.

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
        ``run(k0, k1, h, last, row0)``: steps k0..k1-1 of ``h`` s on buffer rows k - row0;
        ``last`` is the number of steps of the run (Jacobi reads no outputs after the last
        one).
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
        lines[mark:mark] = [f"        {r}_next = b{r} + (k + 1 - row0) * s{r}"
                            for r in rows.values()]
    lines[head:head] = [f"    {r} = b{r} + (k - row0) * s{r}" for r in exchange_rows]
    params = ", ".join(f"{k}={k}" for k in env)
    src = (f"def run(k0, k1, h, last, row0, {params}):\n"
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
