"""One FMU instance on fmpy, with its message log and raw FMI entry points for the hot loop.

:class:`FmuInstance` calls each FMI function of the FMU's shared library directly (ctypes
function objects with fixed argument types, no per-call wrappers); :class:`Extracted`
unzips each FMU file once for all its instances.
"""
from __future__ import annotations

import ctypes
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException, calloc, free
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

__all__ = ["CosimError", "Extracted", "FmuInstance", "STATUS"]

#: fmi2Status names by value
STATUS = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]


class CosimError(RuntimeError):
    """An FMU refused a call; the message names the FMU, the call and what it logged."""


class FmuInstance:
    """One FMU instance with a message log and raw FMI entry points for the hot loop."""

    def __init__(self, label: str, path: Path, unzip_dir: str, instance_name: str,
                 model_description: Any = None) -> None:
        self.label = label
        self.md = model_description or read_model_description(str(path))
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
        # the same library as a PyDLL: the hot-loop calls keep the GIL (pythonfmu's slaves
        # take it again inside every call; a native FMU just runs), which saves two thread
        # switches per call
        dll = ctypes.PyDLL(self.slave.dll._name, handle=self.slave.dll._handle)
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

    def _log(self, env: int | None, instance: bytes | None, status: int,
             category: bytes | None, message: bytes | None) -> None:
        text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
        self.messages.append((STATUS[status] if 0 <= status < 6 else str(status), text))

    def errors(self) -> str:
        """The messages the FMU logged with status Warning, Discard, Error or Fatal.

        Returns
        -------
        str
            The messages joined by "; ", or a note that the FMU logged none.
        """
        bad = [m for s, m in self.messages if s in ("Error", "Fatal", "Discard", "Warning")]
        return "; ".join(bad) if bad else "(the FMU logged no message)"

    def vrs(self, names: list[str]) -> ctypes.Array:
        """A ctypes array of the value references of ``names``, for the raw FMI calls.

        Parameters
        ----------
        names : list[str]
            FMI scalar variable names.

        Returns
        -------
        ctypes.Array
            ``c_uint`` array of their value references, in the same order.

        Raises
        ------
        KeyError
            If a name is not a variable of the FMU.
        """
        arr = (ctypes.c_uint * len(names))(*[self.vr[n] for n in names])
        return arr

    def fail(self, call: str, status: int) -> CosimError:
        """The error to raise when ``call`` returned ``status`` (the caller raises it).

        Parameters
        ----------
        call : str
            What was called, e.g. "fmi2DoStep at t = 1.0 s".
        status : int
            The fmi2Status it returned.

        Returns
        -------
        CosimError
            Naming the FMU, the call, the status and what the FMU logged.
        """
        return CosimError(f"{self.label} FMU: {call} returned "
                          f"{STATUS[status] if 0 <= status < 6 else status}: {self.errors()}")

    def initialize(self, parameters: dict[str, Any], T: float) -> None:
        """Set up the experiment on [0, T], set the parameters, leave initialization mode.

        Parameters
        ----------
        parameters : dict[str, Any]
            FMI scalar name -> value (Real, Integer or String variables).
        T : float
            Stop time, s.

        Raises
        ------
        CosimError
            If an FMI call fails, with what the FMU logged.
        """
        s = self.slave
        try:
            s.setupExperiment(startTime=0.0, stopTime=T)
            s.enterInitializationMode()
            reals = [(self.vr[k], float(v)) for k, v in parameters.items()
                     if self.types[k] == "Real"]
            ints = [(self.vr[k], int(v)) for k, v in parameters.items()
                    if self.types[k] == "Integer"]
            strs = [(self.vr[k], str(v)) for k, v in parameters.items()
                    if self.types[k] == "String"]
            if reals:
                s.setReal(*map(list, zip(*reals)))
            if ints:
                s.setInteger(*map(list, zip(*ints)))
            if strs:
                s.setString(*map(list, zip(*strs)))
            s.exitInitializationMode()
        except FMICallException as exc:
            raise CosimError(f"{self.label} FMU: initialization failed ({exc}): "
                             f"{self.errors()}") from None

    def close(self) -> None:
        """Terminate (ignoring a failure) and free the instance."""
        try:
            self.slave.terminate()
        except FMICallException:
            pass
        self.slave.freeInstance()


class Extracted:
    """FMUs unzipped once per master, removed at the end."""

    def __init__(self, fmus: dict[str, Path]) -> None:
        self.root = Path(tempfile.mkdtemp(prefix="auv_cosim_"))
        self.dirs = {k: extract(str(p), unzipdir=str(self.root / k)) for k, p in fmus.items()}

    def cleanup(self) -> None:
        """Remove the unzipped FMUs."""
        shutil.rmtree(self.root, ignore_errors=True)
