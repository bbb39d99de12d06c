"""The FMI plumbing shared by the three slaves: arrays in, arrays out, errors as statuses.

A slave subclasses :class:`ArraySlave` and supplies ``interface(config)`` (its list of
:class:`~fmu_common.interface.ArraySpec`), ``setup()`` (build the mathematics from ``self.par``,
called in exitInitializationMode), ``compute_outputs()`` (fill ``self.io[name]``) and
``advance(step)``. The base class expands the arrays into FMI scalars backed by one contiguous
input and one output buffer (batched get/set), computes outputs lazily, and turns failures
into FMI statuses with a logged message; the FMU state is :mod:`fmu_common.fmu_state`. How
errors reach the host under pythonfmu 0.7: docs/fmu-internals.md.
"""
from __future__ import annotations

import json
import math
import struct
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

from .fmu_state import (
    STATE_FORMAT,
    STATE_MAGIC,
    FmuState,
    FmuStateMixin,
    StateError,
    decode_state,
    encode_state,
)
from .interface import ArraySpec, expand

if TYPE_CHECKING:
    from pythonfmu.variables import ScalarVariable

# the state names are re-exported: slaves and tests import them from here
__all__ = ["STATE_FORMAT", "STATE_MAGIC", "ArraySlave", "FmuState", "StateError",
           "decode_state", "encode_state", "load_config"]

_CAUSALITY = {"parameter": Fmi2Causality.parameter, "input": Fmi2Causality.input,
              "output": Fmi2Causality.output}
_VARIABILITY = {"fixed": Fmi2Variability.fixed, "tunable": Fmi2Variability.tunable,
                "continuous": Fmi2Variability.continuous,
                "discrete": Fmi2Variability.discrete}
_TYPES = {"Real": Real, "Integer": Integer, "String": String}

#: Python objects pythonfmu's C++ layer released after a fatal error (docs/fmu-internals.md).
_RELEASED_AFTER_FATAL: list[Any] = []


def load_config(resources: str | None, filename: str) -> dict[str, Any]:
    """The build-time configuration (dimensions and start values) shipped in resources/.

    Parameters
    ----------
    resources : str or None
        The FMU's resources folder; None: the project root (a slave used outside an FMU).
    filename : str
        Name of the JSON file.

    Returns
    -------
    dict[str, Any]
        The parsed configuration.

    Raises
    ------
    FileNotFoundError
        If the file is not in the folder.
    """
    here = Path(resources) if resources else Path(__file__).resolve().parent.parent
    path = here / filename
    if not path.exists():
        raise FileNotFoundError(f"FMU configuration {filename} not found in {here}")
    return json.loads(path.read_text())


class ArraySlave(FmuStateMixin, Fmi2Slave):
    """Base class of the project's slaves (see the module docstring)."""

    #: name of the JSON configuration file in the FMU's resources/
    config_file: str = ""
    #: name of the parameter that fixes the sample period, if the slave has one
    step_parameter: str | None = None

    # ------------------------------------------------------------------ hooks
    @staticmethod
    def interface(config: dict[str, Any]) -> list[ArraySpec]:  # pragma: no cover
        """The slave's interface table (parameters, inputs, outputs) for ``config``.

        Parameters
        ----------
        config : dict[str, Any]
            The build configuration (:func:`load_config`).

        Returns
        -------
        list[ArraySpec]
            The arrays to register, in any order.

        Raises
        ------
        NotImplementedError
            In the base class: every slave supplies its own.
        """
        raise NotImplementedError

    def setup(self) -> None:  # pragma: no cover
        """Build the mathematics from ``self.par`` (called in exitInitializationMode).

        Raises
        ------
        NotImplementedError
            In the base class: every slave supplies its own.
        """
        raise NotImplementedError

    def compute_outputs(self) -> None:  # pragma: no cover
        """Fill the output arrays ``self.io[name]`` from the current inputs.

        Raises
        ------
        NotImplementedError
            In the base class: every slave supplies its own.
        """
        raise NotImplementedError

    def advance(self, step: float) -> None:  # pragma: no cover
        """Advance the mathematics over one communication step.

        Parameters
        ----------
        step : float
            The communication step, s.

        Raises
        ------
        NotImplementedError
            In the base class: every slave supplies its own.
        """
        raise NotImplementedError

    #: True if :meth:`restore_model_state` rebuilds everything ``compute_outputs`` and
    #: ``advance`` need from the state alone (no ``setup()`` when parameters changed)
    restores_math_from_state: bool = False

    def model_state(self) -> Any:
        """What evolves in the mathematics, as plain Python / numpy copies (initialized only).

        Returns
        -------
        Any
            A tree of dicts with str keys, lists, scalars and numeric arrays
            (:func:`encode_state` serializes it); None in the base class.
        """
        return None

    def restore_model_state(self, state: Any) -> None:
        """Restore :meth:`model_state`; validate first, leaving the mathematics unchanged.

        Parameters
        ----------
        state : Any
            A result of :meth:`model_state` (decoded from a serialized FMU state).

        Raises
        ------
        ValueError
            Naming the problem, if ``state`` does not fit this instance.
        """

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
        self._init_state()
        self._in_bytes = memoryview(self._in).cast("B")     # what set plans write into
        # plans by tuple of value references, and by first reference: (list, plan)
        self._get_plans: dict[tuple, Callable[[], list]] = {}
        self._set_plans: dict[tuple, Callable[[list], None]] = {}
        self._get_index: dict[int, tuple[list, Callable[[], list]]] = {}
        self._set_index: dict[int, tuple[list, Callable[[list], None]]] = {}
        self._bind_fast_paths()
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

    def _make_variable(self, spec: ArraySpec, i: int, name: str) -> ScalarVariable:
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
    def _set_parameter(self, spec: ArraySpec, name: str, target: tuple[np.ndarray, int] | None,
                       value: Any) -> None:
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

    def _check_inputs(self) -> None:
        """Flag the first non-finite input, if any (after a block of inputs was set)."""
        msg = self._first_bad_input()
        if msg is not None:
            self._flag_input(msg)

    def _first_bad_input(self) -> str | None:
        bad = np.flatnonzero(~np.isfinite(self._in))
        if not bad.size:
            return None
        var = self.vars[self._vr_in + int(bad[0])]
        return f"input {var.name} = {self._in[bad[0]]} is not finite"

    # --------------------------------------------------------- fast get/set
    # pythonfmu's fmi2GetReal / fmi2SetReal call get_real(vrs) / set_real(vrs, values) with a
    # new list of value references each time; a co-simulation master passes the same few
    # lists at every step. A plan (a closure over one slice of a buffer) is made once per
    # list and found again by the list's first value reference: one dict lookup and one
    # list comparison per call (hashing tuple(vrs) cost about twice that). Lists that share
    # a first reference fall back to a dict keyed by the whole tuple.
    _PLAN_CACHE_SIZE = 256

    def _outputs_view(self, buf: np.ndarray) -> np.ndarray:
        if self._dirty and self._initialized:
            self.compute_outputs()
            self._dirty = False
        return buf

    def get_real(self, vrs: list[int]) -> list[float]:
        """fmi2GetReal: the values of the Real variables ``vrs`` (outputs computed lazily).

        Parameters
        ----------
        vrs : list[int]
            Value references.

        Returns
        -------
        list[float]
            Their values, in the order of ``vrs``.

        Raises
        ------
        TypeError
            If a value reference is not a Real variable.
        """
        # shadowed on every instance by the closure of _bind_fast_paths (same result)
        return self._get_planned(vrs)

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        """fmi2SetReal: set the Real variables ``vrs`` (a non-finite input refuses the next step).

        Parameters
        ----------
        vrs : list[int]
            Value references.
        values : list[float]
            Their new values, in the order of ``vrs``.

        Raises
        ------
        TypeError
            If a value reference is not a Real variable.
        """
        # shadowed on every instance by the closure of _bind_fast_paths (same result)
        self._set_planned(vrs, values)

    def _bind_fast_paths(self) -> None:
        """Set ``get_real`` / ``set_real`` on the instance: closures over the plan indexes.

        pythonfmu calls them by name on the instance (PyObject_CallMethod), which finds
        a function in the instance's dict before the class's method: no bound method is
        made per call and the closures read cells instead of attributes of ``self``.
        """
        get_index, set_index = self._get_index, self._set_index
        get_planned, set_planned = self._get_planned, self._set_planned

        def get_real(vrs: list[int]) -> list[float]:
            try:
                key, plan = get_index[vrs[0]]
            except (IndexError, KeyError):
                return get_planned(vrs)
            if key != vrs:
                return get_planned(vrs)
            return plan()

        def set_real(vrs: list[int], values: list[float]) -> None:
            try:
                key, plan = set_index[vrs[0]]
            except (IndexError, KeyError):
                return set_planned(vrs, values)
            if key != vrs:
                return set_planned(vrs, values)
            plan(values)

        self.get_real, self.set_real = get_real, set_real

    def _get_planned(self, vrs: list[int]) -> list[float]:
        plan = self._cached_plan(vrs, self._get_plans, self._get_index, self._plan_get)
        return plan()

    def _set_planned(self, vrs: list[int], values: list[float]) -> None:
        plan = self._cached_plan(vrs, self._set_plans, self._set_index, self._plan_set)
        plan(values)

    def _cached_plan(self, vrs: list[int], plans: dict, index: dict, make: Callable) -> Callable:
        key = tuple(vrs)
        plan = plans.get(key)
        if plan is None:
            plan = make(vrs)
            if len(plans) >= self._PLAN_CACHE_SIZE:
                plans.clear()
            plans[key] = plan
        if vrs:
            if len(index) >= self._PLAN_CACHE_SIZE:
                index.clear()
            index[vrs[0]] = (list(vrs), plan)
        return plan

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
            view = self._out[span[0]:span[1]]        # a view: the buffer is updated in place

            def plan() -> list:
                if self._dirty and self._initialized:        # self._outputs_view, inlined
                    self.compute_outputs()
                    self._dirty = False
                return view.tolist()
        else:
            getters = []
            for vr in vrs:
                var = self.vars[vr]
                if not isinstance(var, Real):
                    raise TypeError(f"variable {var.name} (valueReference {vr}) is not a Real")
                getters.append(var.getter)

            def plan() -> list:
                return [float(g()) for g in getters]
        return plan

    def _plan_set(self, vrs: list[int]) -> Callable[[list], None]:
        span = self._contiguous(vrs, self._vr_in, self._in.size)
        if span is not None:
            a, b = span
            # struct writes the doubles into the buffer about twice as fast as numpy converts
            # a list (the same IEEE values: PyFloat_AsDouble either way)
            pack, mem, offset = struct.Struct(f"={b - a}d").pack_into, self._in_bytes, a * 8
            check = self._check_inputs

            if self._feeds[a:b].any():
                def plan(values: list) -> None:
                    pack(mem, offset, *values)
                    self._dirty = True
                    total = sum(values)
                    if total - total != 0.0:          # some value is nan or +-inf (or overflow)
                        check()
            else:
                def plan(values: list) -> None:
                    pack(mem, offset, *values)
                    total = sum(values)
                    if total - total != 0.0:
                        check()
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
        return plan

    # ----------------------------------------------------------- lifecycle
    def _fatal(self, msg: str) -> None:
        self.log(msg, Fmi2Status.error)
        # pythonfmu's C++ layer releases these twice (at the error and in freeInstance)
        keep = (self, type(self), self.log_queue)
        _RELEASED_AFTER_FATAL.extend([keep, keep])
        raise RuntimeError(msg)

    def exit_initialization_mode(self) -> None:
        """fmi2ExitInitializationMode: build the mathematics (:meth:`setup`) from the parameters.

        Raises
        ------
        RuntimeError
            If :meth:`setup` fails (logged first; pythonfmu 0.7 turns it into fmi2Fatal,
            see docs/fmu-internals.md).
        """
        try:
            self.setup()
        except Exception as exc:
            self._fatal(f"{self.modelName} instance '{self.instance_name}': "
                        f"initialization failed: {exc}")
        self._sample_period = (None if self.step_parameter is None
                               else float(self.par[self.step_parameter]))
        self._initialized = True
        self._dirty = True

    def do_step(self, current_time: float, step_size: float) -> bool:
        """fmi2DoStep: advance one communication step, or refuse it with a logged reason.

        A step is refused after a rejected fmi2SetFMUstate, before initialization, while an
        input is not finite, when ``step_size`` differs from the sample period, or when
        :meth:`advance` raises.

        Parameters
        ----------
        current_time : float
            Time at the start of the step, s.
        step_size : float
            Communication step, s.

        Returns
        -------
        bool
            True if the step was taken (pythonfmu: fmi2OK), False if refused (fmi2Discard).
        """
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
        except Exception:
            self.log(f"step at t = {current_time} s failed:\n{traceback.format_exc()}",
                     Fmi2Status.error)
            return False
        self._dirty = True
        return True

