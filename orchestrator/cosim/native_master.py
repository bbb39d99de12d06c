"""The compiled master: the step plan of :func:`orchestrator.cosim.plan.plan_steps` run by
a small C loop (``native_master.c``) instead of the Python loop of ``compile_plan``.

The same plan (Gauss-Seidel or Jacobi, the batched get / set calls, the FMUs reading and
writing the numpy trace arrays in place, t = k h computed) goes to C as arrays of raw
function pointers, component pointers, value-reference arrays, counts, row-0 addresses and
row strides; the traces come back in the same arrays, equal to the Python master's bit for
bit. The ``when`` condition of a connection (the truth signals in mode ``ideal``) is a
fixed parameter value, resolved when the plan is made: a connection that carries nothing
is not in the plan, for either master. The recording stride applies to the traces after
the run (:mod:`orchestrator.recording`), as with the Python master.

Which master runs (:func:`choose_master`): ``native`` when asked, or by default
(``auto``) when every component is a native FMU (``auv-cosim native``) and the library
builds; ``python`` otherwise. The library is compiled at first use with the system C
compiler (:func:`orchestrator.cosim.native.compiler`, the native FMUs' flags) into the
FMU cache folder (:func:`orchestrator.cosim.build.fmu_cache_dir`), named by a digest of its
source, the flags and the compiler.

Threads, the GIL and signals. The loop is called through :class:`ctypes.CDLL`, which
releases the GIL, on a thread of its own; the calling thread waits on it in slices of
50 ms, updates the progress bar from the step count the loop stores, and copies the
:class:`~orchestrator.interrupt.StopFlag` (set by the Python signal handler, which runs in
the main thread while it waits) into an int the loop reads before every step. A second
signal (KeyboardInterrupt in the waiting thread) stops the loop and waits for it before
the FMUs are freed. A pythonfmu FMU in the plan (``--master native`` with the acoustic
network or a nonlinear vehicle) is safe there: pythonfmu 0.7's binary takes the GIL itself
around every FMI call (``PyGILState_Ensure`` / ``Release``), its slave's Python code then
runs on the loop's thread, and the fmpy logger callbacks take the GIL as every ctypes
callback does. It costs a GIL hand-over per pythonfmu call.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import tempfile
import threading
from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = ["MASTERS", "MASTER_CHOICES", "choose_master", "is_native_fmu", "load_library",
           "run_native_loop"]

#: the masters that can run a plan
MASTERS = ("native", "python")
#: what a caller may ask for: ``auto`` picks (module docstring)
MASTER_CHOICES = ("auto", *MASTERS)
SOURCE = Path(__file__).with_name("native_master.c")
#: how often the waiting thread looks at the stop flag and the progress, s
POLL_S = 0.05


class _Call(ctypes.Structure):
    _fields_ = [("fn", ctypes.c_void_p), ("component", ctypes.c_void_p),
                ("vr", ctypes.c_void_p), ("n", ctypes.c_size_t), ("base", ctypes.c_void_p),
                ("stride", ctypes.c_int64)]


class _Step(ctypes.Structure):
    _fields_ = [("fn", ctypes.c_void_p), ("component", ctypes.c_void_p)]


class _Failure(ctypes.Structure):
    _fields_ = [("phase", ctypes.c_int32), ("index", ctypes.c_int32),
                ("status", ctypes.c_int32)]


_LIBRARY: ctypes.CDLL | None = None
_LOCK = threading.Lock()


def library_path() -> Path:
    """Where the compiled loop is kept: ``<fmu cache>/native_master-<digest>.so``.

    Raises
    ------
    NativeBuildError
        If there is no C compiler.
    """
    from .build import fmu_cache_dir
    from .native import CFLAGS, compiler
    digest = hashlib.sha256(SOURCE.read_bytes())
    digest.update(repr((CFLAGS, compiler())).encode())
    return fmu_cache_dir() / f"native_master-{digest.hexdigest()[:16]}.so"


def load_library() -> ctypes.CDLL:
    """The compiled loop, built at first use (once per process, atomically on disk).

    Returns
    -------
    ctypes.CDLL
        With ``auv_master_run`` typed.

    Raises
    ------
    NativeBuildError
        No compiler, or it failed (its first error line).
    """
    global _LIBRARY
    with _LOCK:
        if _LIBRARY is not None:
            return _LIBRARY
        from .native_build import CFLAGS, compiler, run_compiler
        path = library_path()
        if not path.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, part = tempfile.mkstemp(prefix=".native_master-", suffix=".so",
                                        dir=path.parent)
            os.close(fd)
            try:
                run_compiler([compiler(), *CFLAGS, "-o", part, str(SOURCE)],
                             "the compiled master")
                os.replace(part, path)
            finally:
                if os.path.exists(part):
                    os.unlink(part)
        lib = ctypes.CDLL(str(path))
        fn = lib.auv_master_run
        P = ctypes.POINTER
        fn.argtypes = [P(_Call), ctypes.c_int32, P(_Step), ctypes.c_int32, P(_Call),
                       ctypes.c_int32, ctypes.c_int64, ctypes.c_int64, ctypes.c_double,
                       ctypes.c_int64, ctypes.c_int64, P(ctypes.c_int32), P(ctypes.c_int64),
                       P(_Failure), ctypes.c_void_p]
        fn.restype = ctypes.c_int64
        _LIBRARY = lib
        return lib


def is_native_fmu(model_description: Any) -> bool:
    """True for compiled code with no Python inside: an FMU of
    :mod:`orchestrator.cosim.native`, or another (a user's vehicle FMU) not made by
    pythonfmu and not needing an execution tool."""
    tool = model_description.generationTool or ""
    cs = model_description.coSimulation
    return tool.startswith("auv-cosim native") or (
        "pythonfmu" not in tool.lower() and cs is not None and not cs.needsExecutionTool)


def choose_master(requested: str, model_descriptions: Mapping[str, Any]) -> tuple[str, str]:
    """The master that runs a system, and why.

    Parameters
    ----------
    requested : str
        One of :data:`MASTER_CHOICES`.
    model_descriptions : Mapping[str, Any]
        Component name -> its FMU's model description (fmpy).

    Returns
    -------
    master : str
        ``native`` or ``python``.
    reason : str
        One line: asked for, or why ``auto`` chose it.

    Raises
    ------
    ValueError
        If ``requested`` is not a choice.
    NativeBuildError
        ``native`` asked for and the library cannot be built.
    """
    if requested not in MASTER_CHOICES:
        raise ValueError(f"master {requested!r} is not one of {', '.join(MASTER_CHOICES)}")
    if requested == "python":
        return "python", "asked for"
    from .native import NativeBuildError
    if requested == "native":
        try:
            load_library()
        except NativeBuildError as exc:
            raise NativeBuildError(f"master native: {exc}") from None
        return "native", "asked for"
    others = sorted(c for c, md in model_descriptions.items() if not is_native_fmu(md))
    if others:
        return "python", (f"{len(others)} component(s) are not native FMUs "
                          f"({', '.join(others[:3])}{', ...' if len(others) > 3 else ''})")
    try:
        load_library()
    except NativeBuildError as exc:
        return "python", f"the compiled master is not available: {exc}"
    return "native", "every component is a native FMU"


def _calls(ops: list[tuple]) -> ctypes.Array:
    arr = (_Call * max(1, len(ops)))()
    for i, (fn, comp, vr, n, base, stride, *_rest) in enumerate(ops):
        arr[i] = _Call(ctypes.cast(fn, ctypes.c_void_p).value, comp, vr, n, base, stride)
    return arr


def run_native_loop(plan: Any, k0: int, k1: int, h: float, last: int, bar: Any = None,
                    stop: Any = None, row0: int = 0, pacer: Any = None) -> int:
    """Run macro steps k0 <= k < k1 of ``plan`` (t = k h, h in s) in the compiled loop,
    step k on buffer row k - ``row0``.

    Parameters
    ----------
    plan : StepPlan
        The resolved plan; its Jacobi reads at t = 0 are already done
        (:func:`orchestrator.cosim.plan.initial_reads`).
    k0, k1 : int
        The steps to run.
    h : float
        Communication step, s.
    last : int
        Number of steps of the whole run (Jacobi reads no outputs after the last one).
    bar : Any, optional
        An object with ``update(n)`` (a progress bar), updated every 50 ms.
    stop : StopFlag, optional
        Once true, the loop ends before its next step and keeps the steps simulated.
    row0 : int, optional
        The step whose values are in row 0 of the trace buffers (0: a row per step of the
        run; k0: a buffer of one chunk).
    pacer : Pacer, optional
        Paces the steps to the wall clock in C (:mod:`orchestrator.cosim.pacing`).

    Returns
    -------
    int
        The step reached: k1, or the step at which the stop was found.

    Raises
    ------
    CosimError
        An FMI call failed: the message the Python master gives for the same call.
    """
    fn = load_library().auv_master_run
    exchange, after = _calls(plan.exchange), _calls(plan.after)
    stepping = (_Step * max(1, len(plan.stepping)))()
    for i, (do_step, comp, _) in enumerate(plan.stepping):
        stepping[i] = _Step(ctypes.cast(do_step, ctypes.c_void_p).value, comp)
    flag, reached, fail = ctypes.c_int32(0), ctypes.c_int64(k0), _Failure()
    pace = None
    if pacer is not None:
        pacer.begin(k0)
        pace = ctypes.addressof(pacer.pace)
    out: dict[str, Any] = {}

    def work() -> None:
        try:
            out["k"] = fn(exchange, len(plan.exchange), stepping, len(plan.stepping), after,
                          len(plan.after), k0, k1, h, last, row0, ctypes.byref(flag),
                          ctypes.byref(reached), ctypes.byref(fail), pace)
        except BaseException as exc:            # pragma: no cover - ctypes argument errors
            out["error"] = exc

    loop = threading.Thread(target=work, name="auv-cosim compiled master", daemon=True)
    shown = k0
    loop.start()
    try:
        while loop.is_alive():
            loop.join(POLL_S)
            if stop:
                flag.value = 1
            if bar is not None and reached.value > shown:
                bar.update(reached.value - shown)
                shown = reached.value
    except BaseException:                       # a hard stop: let the loop end first
        flag.value = 1
        loop.join()
        raise
    if "error" in out:
        raise out["error"]
    k = int(out["k"])
    if fail.phase:
        t = k * h
        if fail.phase == 2:
            who = plan.stepping[fail.index][2]
            raise who.fail(f"fmi2DoStep at t = {t} s", fail.status)
        op = (plan.exchange if fail.phase == 1 else plan.after)[fail.index]
        when = t if fail.phase == 1 else (k + 1) * h
        raise op[6].fail(f"{op[7]} at t = {when} s", fail.status)
    if bar is not None and k > shown:
        bar.update(k - shown)
    return k
