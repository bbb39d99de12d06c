"""The FMI plumbing shared by the three slaves: arrays in, arrays out, errors as statuses.

A slave subclasses :class:`ArraySlave` and supplies four things, all plain Python:

- ``interface(config)``: the list of :class:`~fmu_common.interface.ArraySpec`;
- ``setup()``: build the mathematics from the parameter arrays ``self.par``
  (called in exitInitializationMode, so whatever the host set is used);
- ``compute_outputs()``: fill the output views ``self.io[name]`` from the inputs;
- ``advance(step)``: move the internal state over one communication step.

What the base class does for them:

- expands the arrays into FMI scalar variables (``A[1,2]``) whose getters and setters
  read and write numpy arrays; inputs and outputs live in one contiguous buffer each,
  so a master that gets/sets a whole block pays one numpy slice, not one Python call per
  scalar;
- computes outputs lazily: after inputs are set (direct feedthrough) or a step is taken;
- turns failures into FMI statuses with a logged message that names the problem.
  pythonfmu 0.7 maps *any* Python exception to fmi2Fatal, and its C++ layer then drops
  its references to the Python objects while still holding the pointers. So:
  a non-finite input is logged (status error) when set and refused by the next
  fmi2DoStep (fmi2Discard, the instance stays usable); a failure in
  exitInitializationMode (design impossible, bad parameter) is logged and raised, which
  the host sees as fmi2Fatal with the message; the objects the C++ layer lets go of are
  kept alive here so that later calls (terminate, freeInstance) cannot touch freed memory.
- FMU state (canGetAndSetFMUstate, canSerializeFMUstate): see "FMU state" below.

FMU state
---------
fmi2GetFMUstate captures, as a :class:`FmuState` (plain Python and numpy copies):
the parameter values, the input and output buffers, the lazy-output dirty flag, the
pending input error, the sample period, the initialized flag, and the slave's own
``model_state()`` (the plant's s, k, noise row and noise stream, the estimator's q, the
controller's gain). fmi2SetFMUstate restores all of it; the mathematics is rebuilt with
``setup()`` only when the state's parameter values differ from the instance's (or the
instance is not initialized) and the slave cannot rebuild it from the state itself.

fmi2SerializeFMUstate writes (little-endian)::

    b"AUVFMUST" | format u16 | flags u16 | header length u32 | payload length u64 | CRC-32 u32
    | header (UTF-8 JSON) | payload (the numpy arrays' bytes)

The header names what the state belongs to: the model identifier (class name), the
GUID of the build (read from the FMU's modelDescription.xml), a hash of the interface
(names, types, causalities, variabilities and shapes of all variables) with the list of
array names and shapes, and the instance name. Nothing is unpickled: a blob is JSON plus
raw numeric arrays, checked against the lengths and the CRC before use.

What pythonfmu 0.7 allows for errors here: its C++ layer returns fmi2OK from every state
function unless the Python hook raises, and then it returns fmi2Fatal and drops its
references to the instance (the instance is dead for a careful host). fmi2SetFMUstate
ignores the hook's return value and fmi2DeSerializeFMUstate calls a *class* method
(no instance: nothing can be checked against it, nothing logged). So no hook here
raises. A state that cannot be restored (another model, another interface, another
format version, a corrupt or truncated blob, a state that could not be captured) is
handled like a bad input:

- fmi2DeSerializeFMUstate returns fmi2OK and a state object that records the problem;
- fmi2SetFMUstate logs a message with status fmi2Error naming the problem (to a host
  that instantiated with loggingOn), leaves the instance exactly as it was, and
  returns fmi2OK (pythonfmu cannot return anything else without a fatal error);
- the next fmi2DoStep is refused with fmi2Discard and a message repeating the problem,
  so a host that only checks statuses notices; the step after that proceeds normally
  (from the state the instance kept); a successful fmi2SetFMUstate clears the refusal.

A state from another build of the same model and interface (other GUID) is restored,
with a warning naming both GUIDs (pythonfmu gives every build a new GUID).

Other pythonfmu 0.7 details: fmi2SerializedFMUstateSize and fmi2SerializeFMUstate each
call ``_fmu_state_to_bytes`` (the bytes are computed once and kept on the state);
fmi2GetFMUstate always hands out a new state object (a host that passes a non-NULL
*FMUstate to have it updated leaks the old one: free states with fmi2FreeFMUstate).
"""
from __future__ import annotations

import hashlib
import json
import math
import struct
import traceback
import zlib
from pathlib import Path
from typing import Any, Callable
from xml.etree import ElementTree

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

from .interface import ArraySpec, expand

__all__ = ["STATE_FORMAT", "STATE_MAGIC", "ArraySlave", "FmuState", "StateError",
           "decode_state", "encode_state", "load_config"]

_CAUSALITY = {"parameter": Fmi2Causality.parameter, "input": Fmi2Causality.input,
              "output": Fmi2Causality.output}
_VARIABILITY = {"fixed": Fmi2Variability.fixed, "tunable": Fmi2Variability.tunable,
                "continuous": Fmi2Variability.continuous,
                "discrete": Fmi2Variability.discrete}
_TYPES = {"Real": Real, "Integer": Integer, "String": String}

#: Python objects pythonfmu's C++ layer released after a fatal error; see module doc.
_RELEASED_AFTER_FATAL: list[Any] = []


#: first bytes of a serialized FMU state, and the version of the layout after them
STATE_MAGIC = b"AUVFMUST"
STATE_FORMAT = 1
#: magic, format, flags, header length, payload length, CRC-32 of header + payload
_PREFIX = struct.Struct("<8sHHIQI")
#: key marking an array reference in the header's tree
_ND = "__ndarray__"
_UNSET = object()


class StateError(ValueError):
    """A serialized FMU state that cannot be read; the message names the problem."""


class FmuState:
    """What fmi2GetFMUstate / fmi2DeSerializeFMUstate hand to the host (an opaque pointer).

    ``header``: what the state belongs to; ``tree``: the captured values (None if
    ``error``); ``error``: why this state cannot be restored (None for a good state).
    """

    __slots__ = ("_blob", "error", "header", "tree")

    def __init__(self, header: dict[str, Any], tree: Any, error: str | None = None,
                 blob: bytes | None = None) -> None:
        self.header = header
        self.tree = tree
        self.error = error
        self._blob = blob

    def to_bytes(self) -> bytes:
        """The serialized state (computed once: pythonfmu asks for it twice)."""
        if self._blob is None:
            if self.error is not None:
                self._blob = encode_state(dict(self.header, error=self.error), None)
            else:
                self._blob = encode_state(self.header, self.tree)
        return self._blob


def encode_state(header: dict[str, Any], tree: Any) -> bytes:
    """Serialize ``header`` and ``tree`` (dicts with str keys, lists, str, int, float,
    bool, None and numeric numpy arrays) in the layout of the module docstring."""
    arrays: list[np.ndarray] = []
    table: list[dict[str, Any]] = []
    offset = 0

    def enc(obj: Any) -> Any:
        nonlocal offset
        if isinstance(obj, np.ndarray):
            if obj.dtype.kind not in "biuf" or obj.dtype.fields is not None:
                raise TypeError(f"cannot serialize an array of dtype {obj.dtype}")
            a = obj.astype(obj.dtype.newbyteorder("<"), order="C", copy=False)   # keeps 0-d
            table.append({"dtype": a.dtype.str, "shape": list(a.shape), "offset": offset,
                          "nbytes": a.nbytes})
            arrays.append(a)
            offset += a.nbytes
            return {_ND: len(table) - 1}
        if isinstance(obj, dict):
            if _ND in obj:
                raise ValueError(f"key {_ND!r} is reserved")
            out = {}
            for k, v in obj.items():
                if not isinstance(k, str):
                    raise TypeError(f"cannot serialize a dict key of type {type(k).__name__}")
                out[k] = enc(v)
            return out
        if isinstance(obj, (list, tuple)):
            return [enc(v) for v in obj]
        if isinstance(obj, np.generic):
            return enc(obj.item())
        if obj is None or isinstance(obj, (bool, int, float, str)):
            return obj
        raise TypeError(f"cannot serialize a {type(obj).__name__}")

    meta = dict(header)
    meta["tree"] = enc(tree)
    meta["arrays"] = table
    head = json.dumps(meta, separators=(",", ":")).encode("utf-8")
    payload = b"".join(a.tobytes() for a in arrays)
    crc = zlib.crc32(payload, zlib.crc32(head))
    return _PREFIX.pack(STATE_MAGIC, STATE_FORMAT, 0, len(head), len(payload), crc) + head + payload


def decode_state(blob: bytes) -> tuple[dict[str, Any], Any]:
    """(header, tree) of a serialized state; :class:`StateError` naming the problem."""
    n = len(blob)
    if n < _PREFIX.size:
        if n and not STATE_MAGIC.startswith(bytes(blob[:len(STATE_MAGIC)])):
            raise StateError(f"not a serialized state of this FMU family: it starts with "
                             f"{bytes(blob[:8])!r}, not {STATE_MAGIC!r}")
        raise StateError(f"truncated: {n} bytes, shorter than the {_PREFIX.size}-byte prefix "
                         "of a serialized state")
    magic, fmt, _flags, hlen, plen, crc = _PREFIX.unpack_from(blob)
    if magic != STATE_MAGIC:
        raise StateError(f"not a serialized state of this FMU family: it starts with "
                         f"{magic!r}, not {STATE_MAGIC!r}")
    if fmt != STATE_FORMAT:
        raise StateError(f"state format version {fmt}; this FMU reads version {STATE_FORMAT}")
    expected = _PREFIX.size + hlen + plen
    if n < expected:
        raise StateError(f"truncated: {n} bytes, but its prefix announces {expected} "
                         f"({hlen} header + {plen} payload bytes)")
    if n > expected:
        raise StateError(f"{n - expected} unexpected bytes after the end of the state "
                         f"({expected} bytes)")
    body = memoryview(blob)[_PREFIX.size:]
    actual = zlib.crc32(body)
    if actual != crc:
        raise StateError(f"corrupt: CRC-32 {actual:#010x} of the content differs from the "
                         f"stored {crc:#010x}")
    try:
        meta = json.loads(bytes(body[:hlen]).decode("utf-8"))
        table = meta.pop("arrays")
        raw_tree = meta.pop("tree")
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise StateError(f"corrupt header: {exc}") from None
    payload = body[hlen:]
    arrays = []
    try:
        for i, e in enumerate(table):
            dtype = np.dtype(str(e["dtype"]))
            shape = tuple(int(d) for d in e["shape"])
            off, nbytes = int(e["offset"]), int(e["nbytes"])
            count = int(np.prod(shape)) if shape else 1
            if (dtype.kind not in "biuf" or dtype.fields is not None or min(shape, default=0) < 0
                    or nbytes != count * dtype.itemsize or off < 0 or off + nbytes > plen):
                raise StateError(f"corrupt array table: entry {i} {e!r}")
            arrays.append(np.frombuffer(payload, dtype=dtype, count=count, offset=off)
                          .reshape(shape).astype(dtype.newbyteorder("="), copy=True))
    except StateError:
        raise
    except (ValueError, KeyError, TypeError) as exc:
        raise StateError(f"corrupt array table: {exc}") from None

    def dec(obj: Any) -> Any:
        if isinstance(obj, dict):
            if _ND in obj:
                i = obj[_ND]
                if len(obj) != 1 or not isinstance(i, int) or not 0 <= i < len(arrays):
                    raise StateError(f"corrupt array reference {obj!r}")
                return arrays[i]
            return {k: dec(v) for k, v in obj.items()}
        if isinstance(obj, list):
            return [dec(v) for v in obj]
        return obj

    return meta, dec(raw_tree)



def load_config(resources: str | None, filename: str) -> dict[str, Any]:
    """The build-time configuration (dimensions and start values) shipped in resources/."""
    here = Path(resources) if resources else Path(__file__).resolve().parent.parent
    path = here / filename
    if not path.exists():
        raise FileNotFoundError(f"FMU configuration {filename} not found in {here}")
    return json.loads(path.read_text())


class ArraySlave(Fmi2Slave):
    """Base class of the project's slaves (see the module docstring)."""

    #: name of the JSON configuration file in the FMU's resources/
    config_file: str = ""
    #: name of the parameter that fixes the sample period, if the slave has one
    step_parameter: str | None = None

    # ------------------------------------------------------------------ hooks
    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:  # pragma: no cover
        raise NotImplementedError

    def setup(self) -> None:  # pragma: no cover
        raise NotImplementedError

    def compute_outputs(self) -> None:  # pragma: no cover
        raise NotImplementedError

    def advance(self, step: float) -> None:  # pragma: no cover
        raise NotImplementedError

    #: True if :meth:`restore_model_state` rebuilds everything ``compute_outputs`` and
    #: ``advance`` need from the state alone (no ``setup()`` when parameters changed)
    restores_math_from_state: bool = False

    def model_state(self) -> Any:
        """What evolves in the mathematics, as plain Python / numpy copies (initialized only)."""
        return None

    def restore_model_state(self, state: Any) -> None:
        """Restore :meth:`model_state`; validate first and raise ValueError naming the
        problem, leaving the mathematics unchanged."""

    # ---------------------------------------------------------- construction
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.config = load_config(self.resources, self.config_file)
        self.specs = self.interface(self.config)
        self.par: dict[str, Any] = {}
        self.io: dict[str, np.ndarray] = {}
        n_in = sum(s.size for s in self.specs if s.causality == "input")
        n_out = sum(s.size for s in self.specs if s.causality == "output")
        self._in = np.zeros(n_in)
        self._out = np.zeros(n_out)
        self._initialized = False
        self._dirty = True
        self._input_error: str | None = None
        self._sample_period: float | None = None
        #: why the last fmi2SetFMUstate was rejected (the next fmi2DoStep reports it)
        self._state_error: str | None = None
        self._guid: Any = _UNSET
        self._interface_id: tuple[str, list] | None = None
        self._get_plans: dict[tuple, Callable[[], list]] = {}
        self._set_plans: dict[tuple, Callable[[list], None]] = {}
        # specs are registered parameters first, then inputs, then outputs
        order = {"parameter": 0, "input": 1, "output": 2}
        self.specs = sorted(self.specs, key=lambda s: order[s.causality])
        i_in = i_out = 0
        self._feeding = {d for s in self.specs if s.causality == "output" for d in s.depends_on}
        #: input elements that outputs depend on directly (setting them dirties outputs)
        self._feeds = np.zeros(n_in, dtype=bool)
        for spec in self.specs:
            if spec.causality == "input":
                self._feeds[i_in:i_in + spec.size] = spec.name in self._feeding
                self.io[spec.name] = self._in[i_in:i_in + spec.size].reshape(spec.shape)
                self.io[spec.name][...] = np.asarray(spec.start if spec.start is not None else 0.0)
                i_in += spec.size
            elif spec.causality == "output":
                self.io[spec.name] = self._out[i_out:i_out + spec.size].reshape(spec.shape)
                i_out += spec.size
            elif spec.type == "String":
                self.par[spec.name] = str(spec.start)
            else:
                dtype = float if spec.type == "Real" else np.int64
                self.par[spec.name] = np.array(spec.start, dtype=dtype).reshape(spec.shape)
        self._vr_in = self._vr_out = None
        for spec, i, name in expand(self.specs):
            var = self._make_variable(spec, i, name)
            self.register_variable(var)
            vr = var.value_reference
            if spec.causality == "input" and self._vr_in is None:
                self._vr_in = vr
            if spec.causality == "output" and self._vr_out is None:
                self._vr_out = vr

    def _make_variable(self, spec: ArraySpec, i: int, name: str):
        kind = _TYPES[spec.type]
        kw: dict[str, Any] = dict(causality=_CAUSALITY[spec.causality],
                                  variability=_VARIABILITY[spec.fmi_variability],
                                  description=spec.description)
        if spec.causality == "output":
            buf = self.io[spec.name].reshape(-1)
            kw["getter"] = lambda: float(self._outputs_view(buf)[i])
        elif spec.causality == "input":
            buf = self.io[spec.name].reshape(-1)
            kw["getter"] = lambda: float(buf[i])
            feeds = spec.name in self._feeding
            kw["setter"] = lambda v: self._set_input_element(name, buf, i, v, feeds)
        elif spec.type == "String":
            kw["getter"] = lambda: self.par[spec.name]
            kw["setter"] = lambda v: self._set_parameter(spec, name, None, str(v))
        else:
            arr = self.par[spec.name].reshape(-1)
            cast = float if spec.type == "Real" else int
            kw["getter"] = lambda: cast(arr[i])
            kw["setter"] = lambda v: self._set_parameter(spec, name, (arr, i), cast(v))
        return kind(name, **kw)

    # ------------------------------------------------------------- setters
    def _set_parameter(self, spec: ArraySpec, name: str, target, value) -> None:
        if self._initialized and spec.fmi_variability == "fixed":
            self.log(f"parameter {name} is fixed: it cannot change after initialization "
                     f"(value {value!r} ignored)", Fmi2Status.error)
            return
        if target is None:
            self.par[spec.name] = value
        else:
            target[0][target[1]] = value

    def _set_input_element(self, name: str, buf: np.ndarray, i: int, v: float,
                           feeds: bool) -> None:
        buf[i] = v
        if feeds:
            self._dirty = True
        if not math.isfinite(v):
            self._flag_input(f"input {name} = {v} is not finite")

    def _flag_input(self, msg: str) -> None:
        self._input_error = msg
        self.log(f"{msg}; the next step will be refused", Fmi2Status.error)

    def _first_bad_input(self) -> str | None:
        bad = np.flatnonzero(~np.isfinite(self._in))
        if not bad.size:
            return None
        var = self.vars[self._vr_in + int(bad[0])]
        return f"input {var.name} = {self._in[bad[0]]} is not finite"

    # --------------------------------------------------------- fast get/set
    def _outputs_view(self, buf: np.ndarray) -> np.ndarray:
        if self._dirty and self._initialized:
            self.compute_outputs()
            self._dirty = False
        return buf

    def get_real(self, vrs: list[int]) -> list[float]:
        plan = self._get_plans.get(tuple(vrs))
        if plan is None:
            plan = self._plan_get(vrs)
        return plan()

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        plan = self._set_plans.get(tuple(vrs))
        if plan is None:
            plan = self._plan_set(vrs)
        plan(values)

    def _contiguous(self, vrs: list[int], first: int | None, size: int) -> tuple[int, int] | None:
        if first is None or not vrs:
            return None
        a = vrs[0] - first
        if a < 0 or a + len(vrs) > size:
            return None
        if any(vr != vrs[0] + j for j, vr in enumerate(vrs)):
            return None
        return a, a + len(vrs)

    def _plan_get(self, vrs: list[int]) -> Callable[[], list]:
        span = self._contiguous(vrs, self._vr_out, self._out.size)
        if span is not None:
            a, b = span
            out = self._out

            def plan() -> list:
                return self._outputs_view(out)[a:b].tolist()
        else:
            getters = []
            for vr in vrs:
                var = self.vars[vr]
                if not isinstance(var, Real):
                    raise TypeError(f"variable {var.name} (valueReference {vr}) is not a Real")
                getters.append(var.getter)

            def plan() -> list:
                return [float(g()) for g in getters]
        if len(self._get_plans) < 256:
            self._get_plans[tuple(vrs)] = plan
        return plan

    def _plan_set(self, vrs: list[int]) -> Callable[[list], None]:
        span = self._contiguous(vrs, self._vr_in, self._in.size)
        if span is not None:
            a, b = span
            buf = self._in
            feeds = bool(self._feeds[a:b].any())

            def plan(values: list) -> None:
                buf[a:b] = values
                if feeds:
                    self._dirty = True
                total = sum(values)
                if total - total != 0.0:          # some value is nan or +-inf
                    self._flag_input(self._first_bad_input() or "non-finite input")
        else:
            setters = []
            for vr in vrs:
                var = self.vars[vr]
                if not isinstance(var, Real):
                    raise TypeError(f"variable {var.name} (valueReference {vr}) is not a Real")
                setters.append(var.setter)

            def plan(values: list) -> None:
                for s, v in zip(setters, values):
                    s(v)
        if len(self._set_plans) < 256:
            self._set_plans[tuple(vrs)] = plan
        return plan

    # ----------------------------------------------------------- lifecycle
    def _fatal(self, msg: str) -> None:
        self.log(msg, Fmi2Status.error)
        # pythonfmu's C++ layer releases these twice (at the error and in freeInstance)
        keep = (self, type(self), self.log_queue)
        _RELEASED_AFTER_FATAL.extend([keep, keep])
        raise RuntimeError(msg)

    def exit_initialization_mode(self) -> None:
        try:
            self.setup()
        except Exception as exc:  # noqa: BLE001 - every failure must reach the host
            self._fatal(f"{self.modelName} instance '{self.instance_name}': "
                        f"initialization failed: {exc}")
        self._sample_period = (None if self.step_parameter is None
                               else float(self.par[self.step_parameter]))
        self._initialized = True
        self._dirty = True

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self._state_error is not None:
            problem, self._state_error = self._state_error, None
            self.log(f"step at t = {current_time} s refused: the last fmi2SetFMUstate was "
                     f"rejected ({problem}); the instance kept the state it had before that "
                     "call, and the next step proceeds from it", Fmi2Status.error)
            return False
        if not self._initialized:
            self.log("fmi2DoStep called before initialization finished", Fmi2Status.error)
            return False
        if self._input_error is not None:
            msg = self._first_bad_input()
            if msg is not None:
                self.log(f"step at t = {current_time} s refused: {msg}", Fmi2Status.error)
                return False
            self._input_error = None
        h = self._sample_period
        if h is not None and step_size != h:
            if abs(step_size - h) > 1e-9 * h:
                self.log(f"communication step {step_size} s differs from this FMU's sample "
                         f"period {self.step_parameter} = {h} s; set {self.step_parameter} "
                         "to the step you use", Fmi2Status.error)
                return False
        try:
            self.advance(step_size)
        except Exception:  # noqa: BLE001
            self.log(f"step at t = {current_time} s failed:\n{traceback.format_exc()}",
                     Fmi2Status.error)
            return False
        self._dirty = True
        return True

    # ------------------------------------------------------------- FMU state
    def _model_guid(self) -> str | None:
        """The GUID in the FMU's modelDescription.xml (next to resources/), if readable."""
        if self._guid is _UNSET:
            guid = None
            try:
                if self.resources:
                    path = Path(self.resources).parent / "modelDescription.xml"
                    with open(path, "rb") as f:
                        for _, elem in ElementTree.iterparse(f, events=("start",)):
                            guid = elem.get("guid")
                            break
            except Exception:  # noqa: BLE001 - the GUID is informative only
                guid = None
            self._guid = guid
        return self._guid

    def _interface(self) -> tuple[str, list]:
        """(hash, [[name, shape], ...]) of the variables this instance registered."""
        if self._interface_id is None:
            table = [[s.name, s.type, s.causality, s.fmi_variability, list(s.shape)]
                     for s in self.specs]
            digest = hashlib.sha256(json.dumps([type(self).__name__, table]).encode()).hexdigest()
            self._interface_id = (digest[:16], [[s.name, list(s.shape)] for s in self.specs])
        return self._interface_id

    def _state_header(self) -> dict[str, Any]:
        digest, arrays = self._interface()
        return {"model": type(self).__name__, "guid": self._model_guid(), "interface": digest,
                "variables": arrays, "instance": self.instance_name}

    def _who(self) -> str:
        return f"{type(self).__name__} instance '{self.instance_name}'"

    def _get_fmu_state(self) -> FmuState:
        """fmi2GetFMUstate: a copy of everything that evolves (see the module docstring)."""
        try:
            header = self._state_header()
        except Exception as exc:  # noqa: BLE001 - never raise into pythonfmu
            header = {"model": type(self).__name__}
            self.log(f"{self._who()}: fmi2GetFMUstate could not describe the interface: "
                     f"{exc!r}", Fmi2Status.warning)
        try:
            tree = {
                "initialized": self._initialized,
                "dirty": self._dirty,
                "input_error": self._input_error,
                "sample_period": self._sample_period,
                "inputs": self._in.copy(),
                "outputs": self._out.copy(),
                "parameters": {k: (v if isinstance(v, str) else np.array(v, copy=True))
                               for k, v in self.par.items()},
                "model": self.model_state() if self._initialized else None,
            }
            return FmuState(header, tree)
        except Exception as exc:  # noqa: BLE001
            self.log(f"{self._who()}: fmi2GetFMUstate failed; restoring this state will be "
                     f"refused:\n{traceback.format_exc()}", Fmi2Status.error)
            return FmuState(header, None, error=f"the state could not be captured ({exc!r})")

    def _set_fmu_state(self, state: Any) -> None:
        """fmi2SetFMUstate: restore a state or leave the instance unchanged and report why."""
        try:
            self._state_error = None
            problem = self._state_problem(state)
            if problem is None:
                try:
                    self._restore(state.tree)
                    return
                except Exception as exc:  # noqa: BLE001
                    problem = f"restoring it failed: {exc}"
                    self.log(f"{self._who()}: fmi2SetFMUstate failed:\n{traceback.format_exc()}",
                             Fmi2Status.error)
            self._state_error = problem
            self.log(f"{self._who()}: fmi2SetFMUstate rejected the state: {problem}. The "
                     "instance keeps the state it had; as pythonfmu 0.7 returns fmi2OK here, "
                     "the next fmi2DoStep is refused with fmi2Discard to report it",
                     Fmi2Status.error)
        except Exception:  # noqa: BLE001 - a failure to report must not become fmi2Fatal
            self._state_error = "fmi2SetFMUstate failed unexpectedly"

    def _state_problem(self, state: Any) -> str | None:
        """Why ``state`` cannot be restored into this instance (None: it can)."""
        if not isinstance(state, FmuState):
            return f"it is not a state of this FMU (a {type(state).__name__})"
        if state.error is not None:
            return state.error
        header = state.header
        own = type(self).__name__
        model = header.get("model")
        if model != own:
            return f"it is a state of model {model!r}, not of {own!r}"
        digest, _ = self._interface()
        if header.get("interface") != digest:
            return (f"it was saved by an FMU of model {own} with another interface (built "
                    f"for another scenario or configuration): "
                    f"{self._interface_difference(header)}")
        guid, own_guid = header.get("guid"), self._model_guid()
        if guid and own_guid and guid != own_guid:
            self.log(f"{self._who()}: fmi2SetFMUstate: the state was saved by another build "
                     f"of {own} (GUID {guid}; this FMU has GUID {own_guid}) with the same "
                     "interface; restoring it", Fmi2Status.warning)
        if not isinstance(state.tree, dict):
            return "it holds no data"
        return None

    def _interface_difference(self, header: dict[str, Any]) -> str:
        digest, arrays = self._interface()
        theirs = {str(a[0]): a[1] for a in header.get("variables") or []
                  if isinstance(a, list) and len(a) == 2}
        ours = {name: shape for name, shape in arrays}
        diffs = []
        for name, shape in ours.items():
            if name not in theirs:
                diffs.append(f"{name} is missing from the state")
            elif theirs[name] != shape:
                diffs.append(f"{name} has shape {tuple(theirs[name])} in the state, "
                             f"{tuple(shape)} here")
        extra = [n for n in theirs if n not in ours]
        if extra:
            diffs.append(f"the state has {len(extra)} variable(s) unknown here "
                         f"({', '.join(extra[:3])}{', ...' if len(extra) > 3 else ''})")
        if not diffs:
            diffs.append("same names and shapes, other types or causalities")
        more = f"; and {len(diffs) - 4} more difference(s)" if len(diffs) > 4 else ""
        return (f"{'; '.join(diffs[:4])}{more} (interface hash {header.get('interface')} "
                f"in the state, {digest} here)")

    def _restore(self, tree: dict[str, Any]) -> None:
        """Apply a captured tree; on any error the instance is put back as it was."""
        inputs = _exact_array(tree["inputs"], self._in.shape, "f", "the inputs")
        outputs = _exact_array(tree["outputs"], self._out.shape, "f", "the outputs")
        params = tree["parameters"]
        if not isinstance(params, dict) or set(params) != set(self.par):
            raise ValueError("the state's parameters are not this FMU's parameters")
        for name, value in params.items():
            cur = self.par[name]
            if isinstance(cur, str):
                if not isinstance(value, str):
                    raise TypeError(f"parameter {name} must be a string in the state")
            else:
                _exact_array(value, cur.shape, "iu" if cur.dtype.kind in "iu" else "f",
                             f"parameter {name}")
        initialized = tree["initialized"]
        if not isinstance(initialized, bool) or not isinstance(tree["dirty"], bool):
            raise TypeError("the state's flags are not booleans")
        input_error = tree["input_error"]
        if input_error is not None and not isinstance(input_error, str):
            raise ValueError("the state's pending input error is not a string")
        period = tree["sample_period"]
        if period is not None and not isinstance(period, (int, float)):
            raise ValueError("the state's sample period is not a number")

        same = self._initialized and all(
            (cur == params[k]) if isinstance(cur, str) else
            (np.asarray(params[k], dtype=cur.dtype).tobytes() == cur.tobytes())
            for k, cur in self.par.items())
        saved_dict = dict(self.__dict__)
        saved_in, saved_out = self._in.copy(), self._out.copy()
        saved_par = {k: (v if isinstance(v, str) else v.copy()) for k, v in self.par.items()}
        try:
            for name, value in params.items():
                if isinstance(self.par[name], str):
                    self.par[name] = value
                else:
                    np.copyto(self.par[name], value, casting="unsafe")
            if initialized:
                if not same and not self.restores_math_from_state:
                    self.setup()
                self.restore_model_state(tree["model"])
            self._in[:] = inputs
            self._out[:] = outputs
            self._dirty = tree["dirty"]
            self._input_error = input_error
            self._sample_period = None if period is None else float(period)
            self._initialized = initialized
        except BaseException:
            self.__dict__.clear()
            self.__dict__.update(saved_dict)
            self._in[:] = saved_in
            self._out[:] = saved_out
            for name, value in saved_par.items():
                if isinstance(value, str):
                    self.par[name] = value
                else:
                    np.copyto(self.par[name], value)
            raise

    @staticmethod
    def _fmu_state_to_bytes(state: Any) -> bytes:
        """fmi2SerializedFMUstateSize / fmi2SerializeFMUstate (pythonfmu calls it on the class)."""
        try:
            if isinstance(state, FmuState):
                return state.to_bytes()
            return encode_state({"error": "it is not a state of this FMU "
                                          f"(a {type(state).__name__})"}, None)
        except Exception as exc:  # noqa: BLE001 - never raise into pythonfmu
            return encode_state({"error": f"the state could not be serialized ({exc!r})"}, None)

    @staticmethod
    def _fmu_state_from_bytes(blob: bytes) -> FmuState:
        """fmi2DeSerializeFMUstate (on the class: no instance to check against or log to).

        Never raises: a blob that cannot be read gives a state recording the problem,
        reported when the host sets it (see the module docstring)."""
        try:
            blob = bytes(blob)
            header, tree = decode_state(blob)
            error = header.get("error")
            if error is not None:
                return FmuState(header, None, error=str(error), blob=blob)
            return FmuState(header, tree, blob=blob)
        except StateError as exc:
            return FmuState({}, None, error=f"the serialized state is unusable: {exc}", blob=blob)
        except Exception as exc:  # noqa: BLE001
            return FmuState({}, None, error=f"the serialized state is unusable: {exc!r}",
                            blob=blob if isinstance(blob, bytes) else None)


def _exact_array(value: Any, shape: tuple[int, ...], kinds: str, what: str) -> np.ndarray:
    """``value`` as an array of exactly ``shape`` whose dtype kind is in ``kinds``."""
    if not isinstance(value, np.ndarray) or value.shape != shape or value.dtype.kind not in kinds:
        got = (f"{value.dtype} of shape {value.shape}" if isinstance(value, np.ndarray)
               else type(value).__name__)
        raise ValueError(f"{what} in the state must be an array of shape {shape}, got {got}")
    return value
