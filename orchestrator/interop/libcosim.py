"""Run an exported OSP system in libcosim (Open Simulation Platform) through libcosimpy.

libcosim's fixed-step algorithm steps every simulator, then transfers outputs to inputs:
every FMU sees the other FMUs' outputs of the previous communication point, which
:func:`orchestrator.cosim.master.run_system` with ``coupling="jacobi"`` reproduces bit for
bit.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from ..cosim.instance import pythonfmu_safe_tempdir
from ..cosim.system import SystemDescription

__all__ = ["libcosim_version", "quiet_libcosim", "run_libcosim"]


def libcosim_version() -> dict[str, str]:
    """Versions of libcosimpy and of the libcosim / libcosimc libraries it ships.

    Returns
    -------
    dict[str, str]
        ``libcosimpy`` ("not installed" if missing) and, when readable, ``libcosim`` and
        ``libcosimc``.
    """
    import ctypes
    import importlib.metadata as md
    out = {}
    try:
        out["libcosimpy"] = md.version("libcosimpy")
    except md.PackageNotFoundError:
        return {"libcosimpy": "not installed"}

    class _Version(ctypes.Structure):
        _fields_ = [("major", ctypes.c_int), ("minor", ctypes.c_int), ("patch", ctypes.c_int)]

    try:
        from libcosimpy._internal import libcosimc
        lib = libcosimc()
        for key, fn in (("libcosim", "cosim_libcosim_version"),
                        ("libcosimc", "cosim_libcosimc_version")):
            f = getattr(lib, fn)
            f.restype = _Version
            f.argtypes = []
            v = f()
            out[key] = f"{v.major}.{v.minor}.{v.patch}"
    except Exception:
        pass
    return out


def quiet_libcosim() -> None:
    """Only warnings and errors from libcosim (its default prints every FMI call)."""
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    log_output_level(CosimLogLevel.WARNING)


def run_libcosim(system_file: Path | str, system: SystemDescription, steps: int, *,
                 record: bool = True) -> dict[str, Any]:
    """Run an exported OSP system for ``steps`` steps of ``system.h`` in libcosim.

    libcosimpy, time in integer nanoseconds. Row k of a trace is the value at t = k h that
    libcosim transferred into step k (the outputs read after step k - 1, or after
    initialization for k = 0): the layout of :class:`orchestrator.cosim.master.RunResult`
    with ``coupling="jacobi"``.

    Parameters
    ----------
    system_file : Path or str
        The ``OspSystemStructure.xml`` written from ``system``.
    system : SystemDescription
        The system it describes (its step h, s, and its outputs).
    steps : int
        Number of steps (at least 2).
    record : bool, optional
        False attaches no observer (timing only).

    Returns
    -------
    dict[str, Any]
        ``traces``: {trace name: (steps, size) array} for every output of every component,
        named as :meth:`SystemDescription.trace_names` (None without ``record``);
        ``loop_s``: seconds of stepping over steps 2..steps (the first ``step()`` also
        initializes the FMUs and is left out, as run_system's loop_s leaves out
        initialization); ``setup_s``: seconds to load and connect the system; ``init_s``:
        seconds of the first step; ``loop_steps``: steps - 1.

    Raises
    ------
    ValueError
        If h is not a whole number of nanoseconds or ``steps`` < 2.
    RuntimeError
        If libcosim fails or its observer returns unexpected samples.
    """

    h = float(system.h)
    h_ns = int(round(h * 1e9))
    if h_ns <= 0 or abs(h_ns * 1e-9 - h) > 1e-12 * h:
        raise ValueError(f"h = {h} s is not a whole number of nanoseconds")
    if steps < 2:
        raise ValueError("run_libcosim needs at least 2 steps")
    with pythonfmu_safe_tempdir():      # libcosim unzips the FMUs under TMPDIR
        return _run(system_file, system, steps, record, h_ns)


def _run(system_file: Path | str, system: SystemDescription, steps: int, record: bool,
         h_ns: int) -> dict[str, Any]:
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    t0 = time.perf_counter()
    execution = CosimExecution.from_osp_config_file(str(system_file))
    index = {info.name.decode(): info.index for info in execution.slave_infos()}
    observer = None
    refs: dict[str, tuple[int, list[int]]] = {}
    if record:
        observer = CosimObserver.create_time_series(buffer_size=steps + 1)
        execution.add_observer(observer)
        trace_names = system.trace_names()
        for comp, spec in system.outputs():
            sim = comp.name
            vr = {v.name.decode(): v.reference for v in execution.slave_variables(index[sim])}
            key = trace_names[(sim, spec.name)]
            refs[key] = (index[sim], [vr[n] for n in spec.elements])
            for r in refs[key][1]:
                observer.start_time_series(index[sim], r, CosimVariableType.REAL)
    setup_s = time.perf_counter() - t0

    def fail(what: str) -> RuntimeError:
        from libcosimpy._internal import get_last_error_message
        return RuntimeError(f"libcosim: {what} failed: {get_last_error_message()}")

    t1 = time.perf_counter()
    if not execution.step(1):
        raise fail("initialization and first step")
    init_s = time.perf_counter() - t1
    t1 = time.perf_counter()
    if not execution.simulate_until(steps * h_ns):
        raise fail("simulate_until")
    loop_s = time.perf_counter() - t1
    traces = None
    if record:
        traces = {}
        for s, (slave, vrs) in refs.items():
            cols = []
            for r in vrs:
                # libcosimpy 0.0.6 trims the result by the number of zero step numbers,
                # which drops one sample since step 0 is a real one: ask for one more
                # (steps 0..steps exist: the observer keeps steps + 1 samples)
                _, step_no, values = observer.time_series_real_samples(slave, r, 0, steps + 1)
                step_no, values = list(step_no)[:steps], list(values)[:steps]
                if list(step_no) != list(range(len(step_no))) or len(values) != steps:
                    raise RuntimeError(f"libcosim observer returned steps {step_no[:3]}... "
                                       f"({len(values)} samples) for {s}, expected "
                                       f"0..{steps - 1}")
                cols.append(np.asarray(values, dtype=float))
            traces[s] = np.column_stack(cols)
    del observer, execution          # frees the FMU instances now
    return {"traces": traces, "loop_s": loop_s, "setup_s": setup_s, "init_s": init_s,
            "loop_steps": steps - 1}


