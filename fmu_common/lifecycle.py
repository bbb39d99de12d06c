"""The FMI 2.0 co-simulation state machine, enforced on the slave side.

pythonfmu 0.7 forwards every call to the slave whatever state the instance is in, and lets a
Python slave answer only in three ways: return normally (the host sees fmi2OK), return False
from ``do_step`` (fmi2Discard), or raise (fmi2Fatal, after which pythonfmu's C++ layer drops
its references to the instance). :class:`Fmi2StateMachine` uses those three answers:

- a step the rules forbid (after fmi2Terminate, before initialization, after a fatal error,
  a step size that is not a positive finite number, a communication point other than the
  end of the last step) is refused with fmi2Discard and a logged message (status Error)
  naming the call and the rule; the instance stays as it was;
- any other call out of order (fmi2EnterInitializationMode or fmi2ExitInitializationMode
  twice or out of order, fmi2SetupExperiment after initialization, reading outputs before
  fmi2EnterInitializationMode, a value reference the FMU does not have) is answered with
  fmi2Fatal and a logged message naming the call and the rule (pythonfmu has no fmi2Error
  outside fmi2DoStep); from then on every fmi2DoStep is refused, naming that error.

States (FMI 2.0, section 4.2.4): instantiated -> initialization mode -> step mode ->
terminated; any state -> failed after a fatal answer.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NoReturn

from pythonfmu import Boolean, Fmi2Causality, Integer, String
from pythonfmu.enums import Fmi2Status

__all__ = ["COMM_POINT_TOLERANCE", "FAILED", "Fmi2StateMachine", "INITIALIZING",
           "INSTANTIATED", "STEPPING", "STEP_SIZE_TOLERANCE", "TERMINATED", "TIME_ROUNDING",
           "comm_point_tolerance"]

# The time tolerances of every FMU of the project, the pythonfmu slaves here and the
# native (C) FMUs (written into their generated fmu_tolerances.h by
# orchestrator.cosim.native_build), so both kinds accept and refuse the same calls.
#: a step size within this fraction of a fixed-step FMU's h is h
STEP_SIZE_TOLERANCE = 1e-9
#: a communication point within this fraction of the step (plus :data:`TIME_ROUNDING`) of
#: the end of the last step is that point
COMM_POINT_TOLERANCE = 1e-6
#: the rounding allowed on a communication point, as a fraction of |t| (t = k h computed by
#: the host differs from the FMU's t + h by a few units in the last place)
TIME_ROUNDING = 1e-12


def comm_point_tolerance(expected: float, step: float) -> float:
    """How far (s) a communication point may be from ``expected`` (s), the end of the last
    step, for a step of ``step`` (s): ``COMM_POINT_TOLERANCE step + TIME_ROUNDING |t|``."""
    return COMM_POINT_TOLERANCE * step + TIME_ROUNDING * abs(expected)

INSTANTIATED, INITIALIZING, STEPPING, TERMINATED, FAILED = (
    "instantiated", "initialization mode", "step mode", "terminated", "failed")

#: Python objects pythonfmu's C++ layer released after a fatal error (docs/fmu-internals.md).
_RELEASED_AFTER_FATAL: list[Any] = []


class Fmi2StateMachine:
    """Mixin for a pythonfmu ``Fmi2Slave``: the lifecycle checks of the module docstring.

    The slave calls :meth:`_init_lifecycle` in ``__init__``, tests the common case of a step
    in ``do_step`` and calls :meth:`_step_refusal` otherwise, and sets ``_t_next`` to the
    end of a step it took.
    """

    def _init_lifecycle(self) -> None:
        self._phase = INSTANTIATED
        self._failure: str | None = None
        self._t_next: float | None = None        #: the communication point expected next
        self._start_time = 0.0

    def _who(self) -> str:
        return f"{self.modelName} instance '{self.instance_name}'"

    # ------------------------------------------------------------ answers
    def _fatal(self, msg: str) -> NoReturn:
        """Log ``msg`` (status Error), mark the instance failed and raise (fmi2Fatal)."""
        self.log(msg, Fmi2Status.error)
        self._phase, self._failure = FAILED, msg
        # pythonfmu's C++ layer releases these twice (at the error and in freeInstance)
        keep = (self, type(self), self.log_queue)
        _RELEASED_AFTER_FATAL.extend([keep, keep])
        raise RuntimeError(msg)

    def _out_of_order(self, call: str, rule: str) -> NoReturn:
        self._fatal(f"{self._who()}: {call} refused in state '{self._phase}': {rule} "
                    "(FMI 2.0 co-simulation state machine; pythonfmu 0.7 reports this as "
                    "fmi2Fatal)")

    # --------------------------------------------------------- transitions
    def setup_experiment(self, start_time: float, stop_time: float | None,
                         tolerance: float | None) -> None:
        """fmi2SetupExperiment: only before fmi2EnterInitializationMode.

        Parameters
        ----------
        start_time : float
            Start of the run, s (the first communication point expected).
        stop_time : float or None
            End of the run, s.
        tolerance : float or None
            Not used (fixed-step slaves).
        """
        if self._phase != INSTANTIATED:
            self._out_of_order("fmi2SetupExperiment",
                               "it is allowed only before fmi2EnterInitializationMode")
        if not math.isfinite(start_time):
            self._out_of_order("fmi2SetupExperiment", f"start time {start_time} is not finite")
        self._start_time = float(start_time)

    def enter_initialization_mode(self) -> None:
        """fmi2EnterInitializationMode: once, after instantiation."""
        if self._phase != INSTANTIATED:
            self._out_of_order("fmi2EnterInitializationMode",
                               "it is allowed once, right after instantiation")
        self._phase = INITIALIZING

    def _leave_initialization(self) -> None:
        """Check and record fmi2ExitInitializationMode (the slave builds its math after)."""
        if self._phase != INITIALIZING:
            self._out_of_order("fmi2ExitInitializationMode",
                               "it is allowed once, after fmi2EnterInitializationMode")
        self._phase = STEPPING
        self._t_next = self._start_time

    def terminate(self) -> None:
        """fmi2Terminate: the instance takes no further step."""
        if self._phase == TERMINATED:
            self.log(f"{self._who()}: fmi2Terminate called twice (ignored)",
                     Fmi2Status.warning)
        if self._phase != FAILED:
            self._phase = TERMINATED

    def _after_restore(self, initialized: bool) -> None:
        """A successful fmi2SetFMUstate: step mode again (if initialized), any time next."""
        if self._phase != FAILED and initialized:
            self._phase = STEPPING
            self._t_next = None

    # --------------------------------------------------------------- steps
    def _step_refusal(self, current_time: float, step_size: float) -> str | None:
        """Why fmi2DoStep(current_time, step_size) breaks the rules now (None: it does not).

        ``do_step`` tests the common case (step mode, a positive finite step at the
        expected point) inline and calls this only otherwise, to name the rule broken."""
        call = f"fmi2DoStep(t = {current_time} s, h = {step_size} s)"
        if self._phase != STEPPING:
            why = {INSTANTIATED: "before initialization (fmi2EnterInitializationMode and "
                                 "fmi2ExitInitializationMode come first)",
                   INITIALIZING: "in initialization mode (call fmi2ExitInitializationMode "
                                 "first)",
                   TERMINATED: "after fmi2Terminate (instantiate again, or fmi2Reset)",
                   FAILED: f"after a fatal error ({self._failure})"}[self._phase]
            return f"{call} refused: called {why}"
        if not (math.isfinite(step_size) and step_size > 0.0):
            return f"{call} refused: the communication step size must be a positive number"
        if not math.isfinite(current_time):
            return f"{call} refused: the communication point is not finite"
        expected = self._t_next
        if expected is not None and abs(current_time - expected) > comm_point_tolerance(
                expected, step_size):
            where = "backwards" if current_time < expected else "forwards"
            return (f"{call} refused: the communication point jumps {where} from "
                    f"{expected} s (the end of the last step) to {current_time} s; this FMU "
                    "steps forward in time only (to repeat a step, restore a state with "
                    "fmi2SetFMUstate first)")
        return None

    # ---------------------------------------------------- value references
    def _check_refs(self, call: str, vrs: Sequence[int], kind: type, kind_name: str) -> None:
        """Every value reference exists and has the type of the call (else fmi2Fatal)."""
        for vr in vrs:
            var = self.vars.get(vr)
            if var is None:
                self._out_of_order(call, f"value reference {vr} is not a variable of this "
                                         f"FMU (it has {len(self.vars)} variables, value "
                                         f"references 0 to {len(self.vars) - 1})")
            if not isinstance(var, kind):
                self._out_of_order(call, f"variable {var.name} (value reference {vr}) is not "
                                         f"{kind_name}")

    def _check_settable(self, call: str, vrs: list[int]) -> None:
        for vr in vrs:
            var = self.vars[vr]
            if var.causality == Fmi2Causality.output or var.setter is None:
                self._out_of_order(call, f"variable {var.name} (value reference {vr}) is "
                                         "an output: only inputs and parameters can be set")

    # pythonfmu's own typed get/set, with the value references checked first
    def get_integer(self, vrs: list[int]) -> list[int]:
        self._check_refs("fmi2GetInteger", vrs, Integer, "an Integer")
        return super().get_integer(vrs)

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        self._check_refs("fmi2SetInteger", vrs, Integer, "an Integer")
        self._check_settable("fmi2SetInteger", vrs)
        super().set_integer(vrs, values)

    def get_string(self, vrs: list[int]) -> list[str]:
        self._check_refs("fmi2GetString", vrs, String, "a String")
        return super().get_string(vrs)

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        self._check_refs("fmi2SetString", vrs, String, "a String")
        self._check_settable("fmi2SetString", vrs)
        super().set_string(vrs, values)

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        self._check_refs("fmi2GetBoolean", vrs, Boolean, "a Boolean")
        return super().get_boolean(vrs)

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        self._check_refs("fmi2SetBoolean", vrs, Boolean, "a Boolean")
        super().set_boolean(vrs, values)
