"""One FMU instance on fmpy, with its message log and raw FMI entry points for the hot loop.

:class:`FmuInstance` calls each FMI function of the FMU's shared library directly (ctypes
function objects with fixed argument types, no per-call wrappers); :class:`Extracted`
unzips each FMU file once for all its instances.
"""
from __future__ import annotations

import collections
import ctypes
import itertools
import os
import re
import shutil
import sys
import tempfile
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
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

__all__ = ["CosimError", "Extracted", "FmuInstance", "FmuLog", "STATUS", "pythonfmu_can_load_from",
           "safe_temporary_folder", "pythonfmu_safe_tempdir"]

#: fmi2Status names by value
STATUS = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]


class CosimError(RuntimeError):
    """An FMU refused a call; the message names the FMU, the call and what it logged."""


#: how an FMU logs a non-finite output (fmu_common/slave_base.py, fmu_common/native/fmu_core.c)
_NONFINITE_OUTPUT = re.compile(r"output \S+ = \S+ at t = \S+ s is not finite")


#: characters a resource path may hold for pythonfmu 0.7 to find it: its fmi2Instantiate
#: decodes only "%20" in the resource URI, and a path it cannot open crashes the host
_PYTHONFMU_SAFE_PATH = re.compile(r"[A-Za-z0-9_.~/ -]+")


def pythonfmu_can_load_from(folder: Path | str) -> bool:
    """True if a pythonfmu 0.7 FMU unzipped in ``folder`` can be instantiated: the folder's
    absolute path survives pythonfmu's URI decoding (letters, digits, ``_ . ~ / -`` and
    spaces only; docs/known-problems.md)."""
    return _PYTHONFMU_SAFE_PATH.fullmatch(str(Path(folder).resolve())) is not None


def safe_temporary_folder(prefix: str) -> Path:
    """A new temporary folder pythonfmu FMUs can be unzipped into: under the system's
    temporary folder (``TMPDIR``) when its path is safe, else the first safe one of
    /tmp, /var/tmp and ~/.cache/auv-cosim/tmp.

    Parameters
    ----------
    prefix : str
        Prefix of the folder's name.

    Returns
    -------
    Path
        The folder (created, empty).

    Raises
    ------
    CosimError
        If none of the candidates is safe and writable.
    """
    candidates = [Path(tempfile.gettempdir()), Path("/tmp"), Path("/var/tmp"),
                  Path.home() / ".cache" / "auv-cosim" / "tmp"]
    for base in candidates:
        if not pythonfmu_can_load_from(base):
            continue
        try:
            base.mkdir(parents=True, exist_ok=True)
            return Path(tempfile.mkdtemp(prefix=prefix, dir=base))
        except OSError:
            continue
    raise CosimError("no temporary folder whose path pythonfmu 0.7 can read (only letters, "
                     f"digits, '_.~/-' and spaces): tried {', '.join(map(str, candidates))}; "
                     "set TMPDIR to such a folder")


def _fmu_resources(entry: str) -> bool:
    """``entry`` of sys.path is an FMU's resources folder (pythonfmu puts the folder of
    every FMU it instantiates in front of sys.path and never takes it out) or is gone."""
    p = Path(entry) if entry else None
    if p is None:
        return False
    if not p.exists():
        return True
    return p.name == "resources" and (p.parent / "modelDescription.xml").exists()


@contextmanager
def fmu_free_sys_path() -> Iterator[None]:
    """Within the block, sys.path without the FMUs' resources folders (and vanished
    entries): a process started here (a Dask worker, a seed worker: the spawn start
    method hands the child the parent's sys.path) imports the project's own packages, not
    the copies an FMU ships, from folders that may be deleted under it."""
    saved = list(sys.path)
    sys.path[:] = [e for e in saved if not _fmu_resources(e)]
    try:
        yield
    finally:
        sys.path[:] = saved + [e for e in sys.path if e not in saved]


@contextmanager
def pythonfmu_safe_tempdir() -> Iterator[Path]:
    """Within the block, temporary files of this process and of the native hosts it runs
    (libcosim, fmpy's simulate_ssp: ``TMPDIR`` and :data:`tempfile.tempdir`) go to a
    :func:`safe_temporary_folder`, removed at the end: those hosts unzip FMUs there and
    pythonfmu 0.7 must be able to read the path.

    Yields
    ------
    Path
        The folder.
    """
    base = safe_temporary_folder("auv_host_")
    old_env, old_tempdir = os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"] = tempfile.tempdir = str(base)
    try:
        yield base
    finally:
        tempfile.tempdir = old_tempdir
        if old_env is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = old_env
        shutil.rmtree(base, ignore_errors=True)


def _check_pythonfmu_resources(label: str, md: Any, unzip_dir: str) -> None:
    """Never hand pythonfmu 0.7 a resource folder it would crash on (docs/known-problems.md):
    a path it cannot decode, or a folder without the slave module."""
    if "pythonfmu" not in (md.generationTool or "").lower():
        return
    resources = Path(unzip_dir, "resources")
    if not pythonfmu_can_load_from(unzip_dir):
        raise CosimError(f"{label} FMU: not instantiated: its folder {unzip_dir} has "
                         "characters pythonfmu 0.7 cannot decode in a resource URI (it "
                         "would crash the process); unzip it under a path of letters, "
                         "digits, '_.~/-' and spaces")
    module = resources / "slavemodule.txt"
    name = module.read_text().strip() if module.is_file() else ""
    if not name or not (resources / f"{name}.py").is_file():
        raise CosimError(f"{label} FMU: not instantiated: {resources} holds no slave module "
                         "(slavemodule.txt and the module it names); pythonfmu 0.7 would "
                         "crash the process on it")


#: live message logs by the key each FMU instance passes as its ``componentEnvironment``
_BY_KEY: weakref.WeakValueDictionary[int, FmuLog] = weakref.WeakValueDictionary()
_NEXT_KEY = itertools.count(1)
#: messages that named no live instance (a freed one's late message, a foreign FMU's),
#: the latest few, for a host to inspect
_UNFILED: collections.deque[tuple[str, str, str]] = collections.deque(maxlen=100)


def _file_message(env: int | None, instance: bytes | None, status: int,
                  category: bytes | None, message: bytes | None) -> None:
    """The one logger callback of the process (fmi2CallbackLogger, after fmpy's proxy has
    formatted the message): filed under the instance whose key the FMU passed back as its
    componentEnvironment.

    fmpy's logger proxy (``addLoggerProxy``) keeps a single callback per process: the last
    one given to it. Routing by componentEnvironment, which every FMU hands back unchanged
    with each message, files each message under the instance that logged it whatever the
    instance names (two runs in one process may use the same) and whatever instance was
    made last; and the callback, a module constant, outlives every instance (the proxy
    never calls a freed one)."""
    text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
    name = instance.decode("utf-8", "replace") if isinstance(instance, bytes) else ""
    level = STATUS[status] if 0 <= status < len(STATUS) else str(status)
    log = _BY_KEY.get(env) if env else None
    if log is None:
        _UNFILED.append((name, level, text))
        return
    log.messages.append((level, text))


_LOGGER = fmi2CallbackLoggerTYPE(_file_message)


class FmuLog:
    """The messages of one FMU instance, and the FMI callbacks that file them here.

    ``callbacks`` (an ``fmi2CallbackFunctions``, kept alive by this object) is what
    fmi2Instantiate takes: calloc/free and the process-wide logger, with this log's key as
    the componentEnvironment the FMU hands back with every message."""

    def __init__(self) -> None:
        self.messages: list[tuple[str, str]] = []   #: (status name, text), in order
        self.key = next(_NEXT_KEY)
        _BY_KEY[self.key] = self
        cb = fmi2CallbackFunctions()
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        cb.componentEnvironment = self.key
        cb.logger = _LOGGER
        # fmpy's proxy formats the variadic arguments ctypes cannot pass, then calls
        # _LOGGER for every FMU
        try:
            from fmpy.logging import addLoggerProxy
            addLoggerProxy(ctypes.byref(cb))
        except (ImportError, OSError, AttributeError):  # pragma: no cover - no proxy:
            pass                                         # unformatted, still filed
        self.callbacks = cb

    def errors(self) -> str:
        """The messages logged with status Warning, Discard, Error or Fatal.

        Returns
        -------
        str
            The messages joined by "; ", each on one line (pythonfmu's wrapper logs a
            Python exception over several), or a note that the FMU logged none.
        """
        bad = [" ".join(m.split()) for s, m in self.messages
               if s in ("Error", "Fatal", "Discard", "Warning")]
        return "; ".join(bad) if bad else "(the FMU logged no message)"


class FmuInstance:
    """One FMU instance with a message log and raw FMI entry points for the hot loop."""

    def __init__(self, label: str, path: Path, unzip_dir: str, instance_name: str,
                 model_description: Any = None) -> None:
        self.label = label
        self.md = model_description or read_model_description(str(path))
        _check_pythonfmu_resources(label, self.md, unzip_dir)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.log = FmuLog()
        self.messages = self.log.messages           #: (status name, text) the FMU logged
        self.instance_name = instance_name
        self.slave = FMU2Slave(guid=self.md.guid, unzipDirectory=unzip_dir,
                               modelIdentifier=self.md.coSimulation.modelIdentifier,
                               instanceName=instance_name)
        try:
            self.slave.instantiate(callbacks=self.log.callbacks, loggingOn=True)
        except Exception as exc:        # fmpy: "Failed to instantiate model" (NULL)
            self.slave.freeLibrary()
            raise CosimError(f"{label} FMU: fmi2Instantiate of instance '{instance_name}' "
                             f"returned NULL ({exc}): {self.errors()}") from None
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

    def errors(self) -> str:
        """The messages the FMU logged with status Warning, Discard, Error or Fatal
        (:meth:`FmuLog.errors`)."""
        return self.log.errors()

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
        err = CosimError(f"{self.label} FMU: {call} returned "
                         f"{STATUS[status] if 0 <= status < 6 else status}: {self.errors()}")
        err.label = self.label                  # type: ignore[attr-defined]
        return err

    def nonfinite_output(self) -> str | None:
        """The first non-finite output this FMU logged (``output u[2] = inf at t = 0.04 s is
        not finite``: the pythonfmu slaves and the native FMUs word it alike), or None."""
        for status, text in self.messages:
            m = _NONFINITE_OUTPUT.search(text) if status in ("Error", "Discard") else None
            if m:
                return m.group(0)
        return None

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

    def serialized_state(self) -> bytes:
        """The instance's whole state as bytes (fmi2GetFMUstate, fmi2SerializeFMUstate).

        Raises
        ------
        CosimError
            If the FMU cannot serialize its state (its modelDescription says so) or a call
            fails, naming the FMU.
        """
        cs = self.md.coSimulation
        if not (cs.canGetAndSetFMUstate and cs.canSerializeFMUstate):
            raise CosimError(f"{self.label} FMU: cannot serialize its state "
                             "(canGetAndSetFMUstate / canSerializeFMUstate false): a run "
                             "with it cannot be checkpointed")
        s = self.slave
        try:
            state = s.getFMUState()
            try:
                return bytes(s.serializeFMUstate(state))
            finally:
                s.freeFMUState(state)
        except FMICallException as exc:
            raise CosimError(f"{self.label} FMU: serializing its state failed ({exc}): "
                             f"{self.errors()}") from None

    def restore_state(self, data: bytes) -> None:
        """Set the instance's state from :meth:`serialized_state`'s bytes
        (fmi2DeSerializeFMUstate, fmi2SetFMUstate).

        Raises
        ------
        CosimError
            If a call fails or the FMU logs an error refusing the state (a pythonfmu slave
            refuses that way), naming the FMU.
        """
        s = self.slave
        logged = len(self.messages)
        try:
            state = s.deSerializeFMUstate(data)
            try:
                s.setFMUState(state)
            finally:
                s.freeFMUState(state)
        except FMICallException as exc:
            raise CosimError(f"{self.label} FMU: restoring its state failed ({exc}): "
                             f"{self.errors()}") from None
        refused = [t for st, t in self.messages[logged:] if st in ("Error", "Fatal")]
        if refused:
            raise CosimError(f"{self.label} FMU: refused the saved state: {refused[0]}")

    def close(self) -> None:
        """Terminate (ignoring a failure) and free the instance."""
        try:
            self.slave.terminate()
        except FMICallException:
            pass
        self.slave.freeInstance()


class Extracted:
    """The unzipped folder of each FMU file: from the FMU cache's ``unpacked/`` folder
    (:func:`orchestrator.cosim.unpacked.unpacked_fmu`: unzipped once per content and kept),
    or, where that folder cannot be used (a path pythonfmu cannot read, no space, no
    permission), unzipped into a temporary folder removed by :meth:`cleanup`."""

    def __init__(self, fmus: dict[str, Path]) -> None:
        from .build import fmu_cache_dir
        from .unpacked import unpacked_fmu

        self.root: Path | None = None              # the temporary folder, if one is used
        cache = fmu_cache_dir() / "unpacked"
        self.dirs: dict[str, str] = {}
        for k, p in fmus.items():
            if pythonfmu_can_load_from(cache):
                try:
                    self.dirs[k] = str(unpacked_fmu(p, cache))
                    continue
                except OSError:
                    pass
            if self.root is None:
                self.root = safe_temporary_folder("auv_cosim_")
            self.dirs[k] = str(extract(str(p), unzipdir=str(self.root / k)))

    def cleanup(self) -> None:
        """Remove the temporary folder, if one was used (the cached folders stay)."""
        if self.root is not None:
            shutil.rmtree(self.root, ignore_errors=True)
