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
import traceback
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

from .finite_values import FiniteValues
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
from .lifecycle import (
    COMM_POINT_TOLERANCE,
    FAILED,
    INSTANTIATED,
    STEP_SIZE_TOLERANCE,
    STEPPING,
    TIME_ROUNDING,
    Fmi2StateMachine,
)
from .value_plans import PlannedAccess

if TYPE_CHECKING:
    from pythonfmu.variables import ScalarVariable

# the state names are re-exported: slaves and tests import them from here
__all__ = ["STATE_FORMAT", "STATE_MAGIC", "ArraySlave", "DelegatedStateSlave", "FmuState",
           "StateError", "decode_state", "encode_state", "load_config"]

_CAUSALITY = {"parameter": Fmi2Causality.parameter, "input": Fmi2Causality.input,
              "output": Fmi2Causality.output}
_VARIABILITY = {v: getattr(Fmi2Variability, v) for v in ("fixed", "tunable", "continuous",
                                                         "discrete")}
_TYPES = {"Real": Real, "Integer": Integer, "String": String}


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
    path = (Path(resources) if resources else Path(__file__).resolve().parent.parent) / filename
    if not path.exists():
        raise FileNotFoundError(f"FMU configuration {filename} not found in {path.parent}")
    return json.loads(path.read_text())


class ArraySlave(FiniteValues, FmuStateMixin, PlannedAccess, Fmi2StateMachine, Fmi2Slave):
    """Base class of the project's slaves (see the module docstring)."""

    #: name of the JSON configuration file in the FMU's resources/; by default the slave
    #: module's name with ``_slave`` made ``_config.json`` (:meth:`__init_subclass__`)
    config_file: str = ""
    #: name of the parameter that fixes the sample period, if the slave has one
    step_parameter: str | None = None
    #: the FMUs' author (pythonfmu reads it from the class, its base classes included)
    author: str = "auv-cosim"

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

        Raises NotImplementedError in the base class, as :meth:`interface`.
        """
        raise NotImplementedError

    def compute_outputs(self) -> None:  # pragma: no cover
        """Fill the output arrays ``self.io[name]`` from the current inputs.

        Raises NotImplementedError in the base class, as :meth:`interface`.
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

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Whether the subclass checks its evolving vector; and a slave class in a module
        ``<name>_slave`` reads ``<name>_config.json`` unless it names its own ``config_file``
        (the name orchestrator.cosim.build ships it under)."""
        super().__init_subclass__(**kwargs)
        cls._checks_state = cls.evolving is not ArraySlave.evolving
        stem = cls.__module__.rpartition(".")[2]
        if "config_file" not in cls.__dict__ and stem.endswith("_slave"):
            cls.config_file = stem.removesuffix("_slave") + "_config.json"

    _checks_state = False

    def io_specs(self) -> tuple[list[ArraySpec], list[ArraySpec]]:
        """The input and the output arrays, in order (a native form's interface)."""
        return ([s for s in self.specs if s.causality == "input"],
                [s for s in self.specs if s.causality == "output"])

    def native_form(self) -> Any:
        """The set-up mathematics as a linear form (fmu_common.native_form.NativeForm), for
        a native FMU of the same interface; called after :meth:`setup`.

        Raises
        ------
        NotImplementedError
            For a slave that is not linear (the acoustic network).
        """
        raise NotImplementedError(f"{type(self).__name__} has no native (C) form")

    def evolving(self) -> np.ndarray | None:
        """The array the mathematics advances in a step (checked to stay finite), or None.

        Returns
        -------
        np.ndarray or None
            The current state vector; None in the base class (nothing to check).
        """
        return None

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
        self._init_lifecycle()
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
        self._output_error: str | None = None     #: a refusal of every further step
        self._output_logged: str | None = None    #: the last non-finite output logged
        self._bad_output: str | None = None       #: the outputs' last check found this
        self._param_error: str | None = None
        self._sample_period: float | None = None
        self._init_state()
        self._init_plans()
        # specs are registered parameters first, then inputs, then outputs
        order = {"parameter": 0, "input": 1, "output": 2}
        self.specs = sorted(self.specs, key=lambda s: order[s.causality])
        i_in = i_out = 0
        self._feeding = {d for s in self.specs if s.causality == "output" for d in s.depends_on}
        #: input elements that outputs depend on directly (setting them dirties outputs)
        self._feeds = np.zeros(n_in, dtype=bool)
        #: an output depends on an input directly: outputs are checked at the step's start
        self._feedthrough = bool(self._feeding)
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
        if (spec.min is not None and value < spec.min) or (
                spec.max is not None and value > spec.max):
            msg = (f"parameter {name} = {value!r} is outside its range [{spec.min}, "
                   f"{spec.max}] (value ignored)")
            self.log(msg, Fmi2Status.error)
            if not self._initialized:
                self._param_error = msg
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

    # ----------------------------------------------------------- lifecycle
    def _early_outputs(self) -> None:
        """Outputs read before they are defined: refused before initialization or after a
        fatal error; in initialization mode the current values (start values) are given."""
        if self._phase in (INSTANTIATED, FAILED):
            self._out_of_order("fmi2GetReal", "outputs are defined only from "
                                              "fmi2EnterInitializationMode on, and not after "
                                              "a fatal error")

    def exit_initialization_mode(self) -> None:
        """fmi2ExitInitializationMode: build the mathematics (:meth:`setup`) from the parameters.

        Raises
        ------
        RuntimeError
            If :meth:`setup` fails (logged first; pythonfmu 0.7 turns it into fmi2Fatal,
            see docs/fmu-internals.md).
        """
        self._leave_initialization()
        if self._param_error is None:
            self._param_error = self._first_bad_parameter()
        if self._param_error is not None:
            self._fatal(f"{self._who()}: initialization failed: {self._param_error}")
        try:
            self.setup()
        except Exception as exc:
            self._fatal(f"{self._who()}: initialization failed: {exc}")
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
        expected = self._t_next                     # the state machine's common case, inlined
        if not (self._phase == STEPPING and 0.0 < step_size < math.inf
                and current_time - current_time == 0.0
                and (expected is None or abs(current_time - expected)
                     <= COMM_POINT_TOLERANCE * step_size + TIME_ROUNDING * abs(expected))):
            refusal = self._step_refusal(current_time, step_size)
            if refusal is not None:
                self.log(f"{self._who()}: {refusal}", Fmi2Status.error)
                return False
        if self._output_error is not None:
            self.log(f"{self._who()}: step at t = {current_time} s refused: "
                     f"{self._output_error}", Fmi2Status.error)
            return False
        if self._input_error is not None:
            msg = self._first_bad_input()
            if msg is not None:
                self.log(f"{self._who()}: step at t = {current_time} s refused: {msg}",
                         Fmi2Status.error)
                return False
            self._input_error = None
        h = self._sample_period
        if h is not None and step_size != h:
            if abs(step_size - h) > STEP_SIZE_TOLERANCE * h:
                self.log(f"{self._who()}: communication step {step_size} s differs from "
                         f"this FMU's sample "
                         f"period {self.step_parameter} = {h} s; set {self.step_parameter} "
                         "to the step you use", Fmi2Status.error)
                return False
        if self._dirty:                         # the outputs at t, from this step's inputs,
            self._refresh_outputs()             # unless read (and checked) since they changed
        if self._bad_output is not None:
            self.log(f"{self._who()}: step at t = {current_time} s refused: "
                     f"{self._bad_output}", Fmi2Status.error)
            return False
        try:
            self.advance(step_size)
        except Exception:
            self.log(f"step at t = {current_time} s failed:\n{traceback.format_exc()}",
                     Fmi2Status.error)
            return False
        self._dirty = True
        self._t_next = current_time + step_size
        if self._checks_state:
            state = self.evolving()
            total = sum(state.tolist())
            if total - total != 0.0 and not np.all(np.isfinite(state)):
                return self._nonfinite_step(current_time, step_size, state)
        if not self._feedthrough:               # the outputs at t + h: now, not at a get
            self.compute_outputs()
            self._dirty = False
            total = sum(self._out.tolist())
            if total - total != 0.0:
                msg = self._nonfinite_output()
                if msg is not None:
                    self._output_error = self._output_logged = self._bad_output = msg
                    self.log(f"{self._who()}: {msg} after the step from t = {current_time} s "
                             "(further steps are refused)", Fmi2Status.error)
                    return False
        return True


class DelegatedStateSlave(ArraySlave):
    """A slave whose evolving mathematics is one object, ``getattr(self, math_name)``, with
    ``get_state()`` and ``set_state(state)`` (validating first) and the vector a step
    advances as its attribute ``evolving_name``: the FMU state is that object's state."""

    #: the attribute holding the mathematics (set in ``setup``)
    math_name: str = "plant"
    #: the mathematics' attribute that a step advances (checked to stay finite)
    evolving_name: str = "s"

    def evolving(self) -> np.ndarray:
        """The vector the mathematics advances (checked to stay finite after every step)."""
        return getattr(getattr(self, self.math_name), self.evolving_name)

    def model_state(self) -> Any:
        """The mathematics' own state (its ``get_state()``).

        Returns
        -------
        Any
            Plain values and copies of arrays.
        """
        return getattr(self, self.math_name).get_state()

    def restore_model_state(self, state: Any) -> None:
        """Restore a :meth:`model_state` result (the mathematics' ``set_state``, which
        validates first: ValueError, named by the mathematics, if the state does not fit
        this instance).
        """
        getattr(self, self.math_name).set_state(state)


class VectorStateSlave(ArraySlave):
    """A slave whose whole evolving state is one float vector, its attribute
    ``state_name``: checked to stay finite after every step, saved as a copy, restored
    after checking its shape and finiteness (a ValueError naming the slave otherwise)."""

    #: the attribute holding the state vector
    state_name: str = "s"

    def evolving(self) -> np.ndarray:
        """The state vector (checked to stay finite after every step)."""
        return getattr(self, self.state_name)

    def model_state(self) -> dict[str, np.ndarray]:
        """{state_name: a copy of the state vector}."""
        return {self.state_name: getattr(self, self.state_name).copy()}

    def restore_model_state(self, state: Any) -> None:
        """Restore :meth:`model_state`.

        Raises
        ------
        ValueError
            If the saved vector is not a finite real array of this slave's size.
        """
        now = getattr(self, self.state_name)
        s = state[self.state_name]
        if not (isinstance(s, np.ndarray) and s.shape == now.shape
                and np.all(np.isfinite(s))):
            raise ValueError(f"the {type(self).__name__} state {self.state_name!r} must be a "
                             f"finite real array of {now.size}")
        setattr(self, self.state_name, s.astype(float).copy())
