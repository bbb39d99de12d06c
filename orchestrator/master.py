"""Fixed-step co-simulation master on fmpy for the plant, estimator and controller FMUs.

Within macro step k (t = k h, never accumulated), the exact discrete-time loop
(``coupling="gauss-seidel"``, the default):

    plant  -> y[k], ybar[k] (+ truth)  -> estimator -> xhat, what, zhat
           -> controller -> u[k] -> plant and estimator -> all three doStep(t, h)

``coupling="jacobi"`` does what libcosim's fixed-step algorithm (Open Simulation
Platform) does: every FMU's inputs are set to the other FMUs' outputs read at the
previous communication point, then all three step, then all outputs are read:

    set inputs from the outputs read at t_k -> all three doStep(t_k, h) -> read outputs (t_k+1)

The plant has no direct feedthrough, so the estimator still gets y[k] in step k; but the
estimate it outputs at t_k+1 is computed from its state at k+1 and the inputs it still
holds (y[k]), and reaches the controller in step k+1, whose u reaches the plant in step
k+2: the measurement-to-control path gains latency (see orchestrator/osp_export.py and
tests/test_osp_export.py for the agreement with libcosim). Row k of a Jacobi trace holds
the outputs read at t_k, i.e. the values transferred into step k (u[k] is the control
the plant holds over [t_k, t_k+1)).

The master resolves value references once, calls the FMI functions of each shared
library directly (ctypes, no per-call wrappers), batches each get/set into one call per
FMU, and lets the FMUs read and write the trace arrays in place: row k of the plant's
trace is the buffer fmi2GetReal fills and the buffer the estimator's inputs are set from.
"""
from __future__ import annotations

import ctypes
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE
from fmpy.fmi1 import FMICallException, calloc, free

from fmu_common.interface import element_names
from .fmu_build import FMU_KINDS, interface_of

__all__ = ["CosimError", "FmuInstance", "RunResult", "run_cosimulation", "PLANT_OUTPUTS",
           "ESTIMATOR_OUTPUTS", "LOOP_CONNECTIONS", "COUPLINGS", "signal_names", "signal_size"]

PLANT_OUTPUTS = ("y", "ybar", "x", "w", "z", "e")
ESTIMATOR_OUTPUTS = ("xhat", "what", "zhat")
#: the closed loop's wiring, (source FMU, vector signal, destination FMU), the same
#: variable name at both ends; the system files written for other tools follow it
LOOP_CONNECTIONS: tuple[tuple[str, str, str], ...] = (
    *(("plant", s, "estimator") for s in PLANT_OUTPUTS if s != "e"),
    *(("estimator", s, "controller") for s in ESTIMATOR_OUTPUTS),
    ("controller", "u", "plant"), ("controller", "u", "estimator"),
)
#: how the master couples the FMUs within a step (see the module docstring)
COUPLINGS = ("gauss-seidel", "jacobi")
_STATUS = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]


class CosimError(RuntimeError):
    """An FMU refused a call; the message names the FMU, the call and what it logged."""


class FmuInstance:
    """One FMU instance with a message log and raw FMI entry points for the hot loop."""

    def __init__(self, label: str, path: Path, unzip_dir: str, instance_name: str):
        self.label = label
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.messages: list[tuple[str, str]] = []
        self.slave = FMU2Slave(guid=self.md.guid, unzipDirectory=unzip_dir,
                               modelIdentifier=self.md.coSimulation.modelIdentifier,
                               instanceName=instance_name)
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        try:
            from fmpy.logging import addLoggerProxy
            addLoggerProxy(ctypes.byref(self._callbacks))
        except Exception:  # pragma: no cover - message formatting only
            pass
        self.slave.instantiate(callbacks=self._callbacks, loggingOn=True)
        dll = self.slave.dll
        self.component = self.slave.component

        def raw(name: str, argtypes: list) -> Callable[..., int]:
            f = dll[name]                       # a fresh function object of our own
            f.argtypes = argtypes
            f.restype = ctypes.c_int
            return f

        vp, sz = ctypes.c_void_p, ctypes.c_size_t
        self.get_real = raw("fmi2GetReal", [vp, vp, sz, vp])
        self.set_real = raw("fmi2SetReal", [vp, vp, sz, vp])
        self.do_step = raw("fmi2DoStep", [vp, ctypes.c_double, ctypes.c_double, ctypes.c_int])

    def _log(self, env, instance, status, category, message) -> None:
        text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
        self.messages.append((_STATUS[status] if 0 <= status < 6 else str(status), text))

    def errors(self) -> str:
        bad = [m for s, m in self.messages if s in ("Error", "Fatal", "Discard", "Warning")]
        return "; ".join(bad) if bad else "(the FMU logged no message)"

    def vrs(self, names: list[str]) -> ctypes.Array:
        arr = (ctypes.c_uint * len(names))(*[self.vr[n] for n in names])
        return arr

    def fail(self, call: str, status: int) -> CosimError:
        return CosimError(f"{self.label} FMU: {call} returned {_STATUS[status] if 0 <= status < 6 else status}: "
                          f"{self.errors()}")

    def initialize(self, parameters: dict[str, Any], T: float) -> None:
        s = self.slave
        try:
            s.setupExperiment(startTime=0.0, stopTime=T)
            s.enterInitializationMode()
            reals = [(self.vr[k], float(v)) for k, v in parameters.items() if self.types[k] == "Real"]
            ints = [(self.vr[k], int(v)) for k, v in parameters.items() if self.types[k] == "Integer"]
            strs = [(self.vr[k], str(v)) for k, v in parameters.items() if self.types[k] == "String"]
            if reals:
                s.setReal(*map(list, zip(*reals)))
            if ints:
                s.setInteger(*map(list, zip(*ints)))
            if strs:
                s.setString(*map(list, zip(*strs)))
            s.exitInitializationMode()
        except FMICallException as exc:
            raise CosimError(f"{self.label} FMU: initialization failed ({exc}): {self.errors()}") from None

    def close(self) -> None:
        try:
            self.slave.terminate()
        except FMICallException:
            pass
        self.slave.freeInstance()


def fmu_parameters(kind_name: str, config: dict[str, Any]) -> dict[str, Any]:
    """Scalar parameter values (FMI names) of one FMU for a configuration."""
    out: dict[str, Any] = {}
    for spec in interface_of(FMU_KINDS[kind_name], config):
        if spec.causality != "parameter":
            continue
        if spec.type == "String":
            out[spec.name] = spec.start
            continue
        flat = np.asarray(spec.start).reshape(-1)
        for name, value in zip(element_names(spec.name, spec.shape), flat):
            out[name] = value
    return out


@dataclass
class RunResult:
    """Traces of one co-simulation (row k = sample k, t = k h)."""

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
        return self.traces["u"].shape[0]

    @property
    def t(self) -> np.ndarray:
        return np.arange(self.steps) * self.h


class _Extracted:
    """FMUs unzipped once per master, removed at the end."""

    def __init__(self, fmus: dict[str, Path]):
        self.root = Path(tempfile.mkdtemp(prefix="auv_cosim_"))
        self.dirs = {k: extract(str(p), unzipdir=str(self.root / k)) for k, p in fmus.items()}

    def cleanup(self) -> None:
        shutil.rmtree(self.root, ignore_errors=True)


def run_cosimulation(fmus: dict[str, Path], config: dict[str, Any], *, mode: str, seed: int,
                     steps: int, progress: Any = False, tracking: str | None = None,
                     coupling: str = "gauss-seidel") -> RunResult:
    """Run the three FMUs for ``steps`` communication steps of ``config['h']``.

    ``mode``: the estimator mode; ``tracking``: the controller's law ('lq' or 'regulator',
    default the configuration's). ``progress``: False, True (a progress bar shown after one
    second), or a shared bar object with ``update(n)``. ``coupling``: 'gauss-seidel' (the
    exact discrete-time loop, default) or 'jacobi' (what libcosim does: every FMU sees the
    other FMUs' outputs of the previous communication point; module docstring).
    """
    if coupling not in COUPLINGS:
        raise ValueError(f"coupling {coupling!r} is not one of {', '.join(COUPLINGS)}")
    cfg = dict(config, mode=mode, seed=int(seed),
               tracking=tracking or config.get("tracking", "lq"))
    h = float(cfg["h"])
    d = cfg["dims"]
    n, m, r, p, l_ = d["n"], d["m"], d["r"], d["p"], d["l"]
    ns = n + r + l_
    t0 = time.perf_counter()
    ex = _Extracted(fmus)
    inst: dict[str, FmuInstance] = {}
    try:
        for key in ("plant", "estimator", "controller"):
            inst[key] = FmuInstance(key, fmus[key], ex.dirs[key], f"{key}_{mode}_{seed}")
            inst[key].initialize(fmu_parameters(key, cfg), T=steps * h)
        P, E, C = inst["plant"], inst["estimator"], inst["controller"]
        p_out = signal_names(PLANT_OUTPUTS, d)
        # Jacobi sets every input, as libcosim does (the truth is read only in 'ideal')
        e_meas = p_out[:2 * p + (ns if mode == "ideal" or coupling == "jacobi" else 0)]
        e_out = signal_names(ESTIMATOR_OUTPUTS, d)      # also the controller's inputs
        u_names = element_names("u", (m,))
        vr_p_out, vr_p_u = P.vrs(p_out), P.vrs(u_names)
        vr_e_in, vr_e_u, vr_e_out = E.vrs(e_meas), E.vrs(u_names), E.vrs(e_out)
        vr_c_in, vr_c_out = C.vrs(e_out), C.vrs(u_names)
        rec_p = np.zeros((steps, len(p_out)))
        rec_e = np.zeros((steps, len(e_out)))
        rec_u = np.zeros((steps, m))
        t_loop = time.perf_counter()
        loop = _loop if coupling == "gauss-seidel" else _loop_jacobi
        loop(P, E, C, rec_p, rec_e, rec_u, vr_p_out, vr_p_u, vr_e_in, vr_e_u, vr_e_out,
             vr_c_in, vr_c_out, h, progress)
        loop_s = time.perf_counter() - t_loop
    finally:
        for fmu in inst.values():
            fmu.close()
        ex.cleanup()
    traces: dict[str, np.ndarray] = {}
    for names, rec in ((PLANT_OUTPUTS, rec_p), (ESTIMATOR_OUTPUTS, rec_e)):
        i = 0
        for o in names:
            k = signal_size(o, d)
            traces[o] = rec[:, i:i + k]
            i += k
    traces["u"] = rec_u
    return RunResult(mode=mode, seed=int(seed), h=h, traces=traces,
                     wall_s=time.perf_counter() - t0, loop_s=loop_s, coupling=coupling)


def signal_size(name: str, d: dict[str, int]) -> int:
    """Length of a signal of the loop for the dimensions ``d`` (n, m, r, p, l)."""
    return {"y": d["p"], "ybar": d["p"], "x": d["n"], "w": d["r"], "z": d["l"], "e": d["p"],
            "xhat": d["n"], "what": d["r"], "zhat": d["l"], "u": d["m"]}[name]


def signal_names(signals: tuple[str, ...], d: dict[str, int]) -> list[str]:
    """FMI scalar names of consecutive vector signals, e.g. y[1], y[2], ybar[1], ..."""
    return [nm for o in signals for nm in element_names(o, (signal_size(o, d),))]


def _loop(P, E, C, rec_p, rec_e, rec_u, vr_p_out, vr_p_u, vr_e_in, vr_e_u, vr_e_out,
          vr_c_in, vr_c_out, h, progress) -> None:
    steps = rec_u.shape[0]
    cp, ce, cc = P.component, E.component, C.component
    getP, setP, stepP = P.get_real, P.set_real, P.do_step
    getE, setE, stepE = E.get_real, E.set_real, E.do_step
    getC, setC, stepC = C.get_real, C.set_real, C.do_step
    nPo, nPu, nEi, nEu, nEo, nCi, nCo = (len(vr_p_out), len(vr_p_u), len(vr_e_in),
                                         len(vr_e_u), len(vr_e_out), len(vr_c_in), len(vr_c_out))
    # addresses: value-reference arrays and the rows of the trace arrays
    aPo, aPu, aEi, aEu, aEo, aCi, aCo = (ctypes.addressof(v) for v in
                                         (vr_p_out, vr_p_u, vr_e_in, vr_e_u, vr_e_out, vr_c_in, vr_c_out))
    bp, be, bu = (a.ctypes.data for a in (rec_p, rec_e, rec_u))
    sp, se, su = (a.strides[0] for a in (rec_p, rec_e, rec_u))
    bar = None
    if progress is True:
        from tqdm import tqdm
        bar = tqdm(total=steps, unit="step", delay=1.0, leave=False)
    elif progress:
        bar = progress               # a shared bar (an object with update(n))
    chunk = 2000
    for k0 in range(0, steps, chunk):
        for k in range(k0, min(k0 + chunk, steps)):
            rp, re_, ru = bp + k * sp, be + k * se, bu + k * su
            t = k * h
            st = getP(cp, aPo, nPo, rp)
            if st:
                raise P.fail(f"fmi2GetReal at t = {t} s", st)
            st = setE(ce, aEi, nEi, rp)
            if st:
                raise E.fail(f"fmi2SetReal (measurements) at t = {t} s", st)
            st = getE(ce, aEo, nEo, re_)
            if st:
                raise E.fail(f"fmi2GetReal at t = {t} s", st)
            st = setC(cc, aCi, nCi, re_)
            if st:
                raise C.fail(f"fmi2SetReal at t = {t} s", st)
            st = getC(cc, aCo, nCo, ru)
            if st:
                raise C.fail(f"fmi2GetReal at t = {t} s", st)
            st = setP(cp, aPu, nPu, ru)
            if st:
                raise P.fail(f"fmi2SetReal at t = {t} s", st)
            st = setE(ce, aEu, nEu, ru)
            if st:
                raise E.fail(f"fmi2SetReal (u) at t = {t} s", st)
            st = stepP(cp, t, h, 1)
            if st:
                raise P.fail(f"fmi2DoStep at t = {t} s", st)
            st = stepE(ce, t, h, 1)
            if st:
                raise E.fail(f"fmi2DoStep at t = {t} s", st)
            st = stepC(cc, t, h, 1)
            if st:
                raise C.fail(f"fmi2DoStep at t = {t} s", st)
        if bar is not None:
            bar.update(min(chunk, steps - k0))
    if progress is True:
        bar.close()


def _loop_jacobi(P, E, C, rec_p, rec_e, rec_u, vr_p_out, vr_p_u, vr_e_in, vr_e_u, vr_e_out,
                 vr_c_in, vr_c_out, h, progress) -> None:
    """libcosim's fixed-step coupling: inputs of step k are the outputs read at t_k (after
    step k - 1, or after initialization); all FMUs step; outputs are read at t_k+1.
    Row k of the traces is what was read at t_k."""
    steps = rec_u.shape[0]
    cp, ce, cc = P.component, E.component, C.component
    getP, setP, stepP = P.get_real, P.set_real, P.do_step
    getE, setE, stepE = E.get_real, E.set_real, E.do_step
    getC, setC, stepC = C.get_real, C.set_real, C.do_step
    nPo, nPu, nEi, nEu, nEo, nCi, nCo = (len(vr_p_out), len(vr_p_u), len(vr_e_in),
                                         len(vr_e_u), len(vr_e_out), len(vr_c_in), len(vr_c_out))
    aPo, aPu, aEi, aEu, aEo, aCi, aCo = (ctypes.addressof(v) for v in
                                         (vr_p_out, vr_p_u, vr_e_in, vr_e_u, vr_e_out, vr_c_in, vr_c_out))
    bp, be, bu = (a.ctypes.data for a in (rec_p, rec_e, rec_u))
    sp, se, su = (a.strides[0] for a in (rec_p, rec_e, rec_u))
    bar = None
    if progress is True:
        from tqdm import tqdm
        bar = tqdm(total=steps, unit="step", delay=1.0, leave=False)
    elif progress:
        bar = progress

    def read(k: int, t: float) -> None:
        st = getP(cp, aPo, nPo, bp + k * sp)
        if st:
            raise P.fail(f"fmi2GetReal at t = {t} s", st)
        st = getE(ce, aEo, nEo, be + k * se)
        if st:
            raise E.fail(f"fmi2GetReal at t = {t} s", st)
        st = getC(cc, aCo, nCo, bu + k * su)
        if st:
            raise C.fail(f"fmi2GetReal at t = {t} s", st)

    if steps:
        read(0, 0.0)
    chunk = 2000
    for k0 in range(0, steps, chunk):
        for k in range(k0, min(k0 + chunk, steps)):
            rp, re_, ru = bp + k * sp, be + k * se, bu + k * su
            t = k * h
            st = setP(cp, aPu, nPu, ru)
            if st:
                raise P.fail(f"fmi2SetReal at t = {t} s", st)
            st = setE(ce, aEi, nEi, rp)
            if st:
                raise E.fail(f"fmi2SetReal (measurements) at t = {t} s", st)
            st = setE(ce, aEu, nEu, ru)
            if st:
                raise E.fail(f"fmi2SetReal (u) at t = {t} s", st)
            st = setC(cc, aCi, nCi, re_)
            if st:
                raise C.fail(f"fmi2SetReal at t = {t} s", st)
            st = stepP(cp, t, h, 1)
            if st:
                raise P.fail(f"fmi2DoStep at t = {t} s", st)
            st = stepE(ce, t, h, 1)
            if st:
                raise E.fail(f"fmi2DoStep at t = {t} s", st)
            st = stepC(cc, t, h, 1)
            if st:
                raise C.fail(f"fmi2DoStep at t = {t} s", st)
            if k + 1 < steps:
                read(k + 1, (k + 1) * h)
        if bar is not None:
            bar.update(min(chunk, steps - k0))
    if progress is True:
        bar.close()
