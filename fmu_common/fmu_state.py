"""FMU state of the project's slaves: capture, restore, serialize (fmi2GetFMUstate & co).

:class:`FmuStateMixin` implements pythonfmu's four state hooks for
:class:`fmu_common.slave_base.ArraySlave`; the slave supplies ``model_state()`` /
``restore_model_state(state)`` (and ``restores_math_from_state``). :func:`encode_state` /
:func:`decode_state` write and read the serialized blob (magic ``AUVFMUST``, JSON header,
raw arrays, CRC-32; nothing is unpickled). No hook raises: pythonfmu 0.7 turns a raised
exception into fmi2Fatal, so a state that cannot be restored is logged and the next
fmi2DoStep is refused. What is saved, the byte layout and the error handling:
docs/fmu-internals.md.
"""
from __future__ import annotations

import hashlib
import json
import struct
import traceback
import zlib
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np
from pythonfmu.enums import Fmi2Status

__all__ = ["STATE_FORMAT", "STATE_MAGIC", "FmuState", "FmuStateMixin", "StateError",
           "decode_state", "encode_state"]

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
        """The serialized state (computed once: pythonfmu asks for it twice).

        Returns
        -------
        bytes
            :func:`encode_state` of the header and tree (or of the header and the error).
        """
        if self._blob is None:
            if self.error is not None:
                self._blob = encode_state(dict(self.header, error=self.error), None)
            else:
                self._blob = encode_state(self.header, self.tree)
        return self._blob


def encode_state(header: dict[str, Any], tree: Any) -> bytes:
    """Serialize ``header`` and ``tree`` in the layout of docs/fmu-internals.md.

    Magic, format, flags, header and payload lengths, CRC-32; then the JSON header (with
    the tree, arrays replaced by references into a table) and the raw little-endian arrays.

    Parameters
    ----------
    header : dict[str, Any]
        What the state belongs to (JSON-ready).
    tree : Any
        The captured values: dicts with str keys, lists, str, int, float, bool, None and
        numeric numpy arrays.

    Returns
    -------
    bytes
        The serialized state.

    Raises
    ------
    TypeError
        If the tree holds a value of another type, a non-numeric array or a non-str key.
    ValueError
        If a dict uses the reserved key ``__ndarray__``.
    """
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
    """(header, tree) of a serialized state; :class:`StateError` naming the problem.

    Parameters
    ----------
    blob : bytes
        A result of :func:`encode_state`.

    Returns
    -------
    header : dict[str, Any]
        The header (without the tree and the array table).
    tree : Any
        The captured values, arrays as new native-byte-order copies.

    Raises
    ------
    StateError
        If the blob is truncated, too long, of another family or format version, fails
        its CRC-32, or its header or array table is corrupt.
    """
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


class FmuStateMixin:
    """pythonfmu's FMU-state hooks for :class:`~fmu_common.slave_base.ArraySlave`.

    Uses the slave's ``specs``, ``par``, ``_in``, ``_out``, flags and ``model_state()`` /
    ``restore_model_state()``; keeps ``_guid`` and ``_interface_id`` (set in the slave's
    ``__init__`` by :meth:`_init_state`) and ``_state_error`` (read by ``do_step``).
    """

    def _init_state(self) -> None:
        #: why the last fmi2SetFMUstate was rejected (the next fmi2DoStep reports it)
        self._state_error: str | None = None
        self._guid: Any = _UNSET
        self._interface_id: tuple[str, list] | None = None

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
            except Exception:
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
        """fmi2GetFMUstate: a copy of everything that evolves (see docs/fmu-internals.md)."""
        try:
            header = self._state_header()
        except Exception as exc:
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
        except Exception as exc:
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
                    self._output_error = self._bad_output = self._output_logged = None
                    self._dirty = True          # recomputed and checked before use
                    self._after_restore(bool(state.tree["initialized"]))
                    return
                except Exception as exc:
                    problem = f"restoring it failed: {exc}"
                    self.log(f"{self._who()}: fmi2SetFMUstate failed:\n{traceback.format_exc()}",
                             Fmi2Status.error)
            self._state_error = problem
            self.log(f"{self._who()}: fmi2SetFMUstate rejected the state: {problem}. The "
                     "instance keeps the state it had; as pythonfmu 0.7 returns fmi2OK here, "
                     "the next fmi2DoStep is refused with fmi2Discard to report it",
                     Fmi2Status.error)
        except Exception:
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
        except Exception as exc:
            return encode_state({"error": f"the state could not be serialized ({exc!r})"}, None)

    @staticmethod
    def _fmu_state_from_bytes(blob: bytes) -> FmuState:
        """fmi2DeSerializeFMUstate (on the class: no instance to check against or log to).

        Never raises: a blob that cannot be read gives a state recording the problem,
        reported when the host sets it (see docs/fmu-internals.md)."""
        try:
            blob = bytes(blob)
            header, tree = decode_state(blob)
            error = header.get("error")
            if error is not None:
                return FmuState(header, None, error=str(error), blob=blob)
            return FmuState(header, tree, blob=blob)
        except StateError as exc:
            return FmuState({}, None, error=f"the serialized state is unusable: {exc}", blob=blob)
        except Exception as exc:
            return FmuState({}, None, error=f"the serialized state is unusable: {exc!r}",
                            blob=blob if isinstance(blob, bytes) else None)


def _exact_array(value: Any, shape: tuple[int, ...], kinds: str, what: str) -> np.ndarray:
    """``value`` as an array of exactly ``shape`` whose dtype kind is in ``kinds``."""
    if not isinstance(value, np.ndarray) or value.shape != shape or value.dtype.kind not in kinds:
        got = (f"{value.dtype} of shape {value.shape}" if isinstance(value, np.ndarray)
               else type(value).__name__)
        raise ValueError(f"{what} in the state must be an array of shape {shape}, got {got}")
    return value
