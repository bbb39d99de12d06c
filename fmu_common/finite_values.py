"""Non-finite values in a pythonfmu slave: which input, output, parameter or state element
went nan or +-inf, named with its FMI structured name, its value and the time, logged once
and turned into a refused step (docs/known-problems.md, "Non-finite values").

pythonfmu 0.7 lets a slave answer fmi2DoStep with True (fmi2OK) or False (fmi2Discard);
every other call is fmi2OK unless Python raises (then fmi2Fatal). So a non-finite output is
refused at the next fmi2DoStep, with fmi2Discard and a logged line naming it, as the native
FMUs do. A mixin of :class:`fmu_common.slave_base.ArraySlave`: it uses the slave's buffers
(``_in``, ``_out``), variable tables (``vars``, ``_vr_in``, ``_vr_out``), ``specs``, ``par``,
``compute_outputs`` and ``log``.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from pythonfmu.enums import Fmi2Status

from .interface import element_names

__all__ = ["FiniteValues"]


class FiniteValues:
    """The checks for nan and +-inf of :class:`fmu_common.slave_base.ArraySlave`."""

    _in: np.ndarray
    _out: np.ndarray
    vars: Any
    _vr_in: int
    _vr_out: int
    _t_next: float | None
    _feedthrough: bool
    _dirty: bool
    _input_error: str | None
    _output_error: str | None
    _output_logged: str | None
    _bad_output: str | None

    def _flag_input(self, msg: str) -> None:
        self._input_error = msg
        self.log(f"{self._who()}: {msg}; the next step will be refused", Fmi2Status.error)

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

    def _check_outputs(self) -> None:
        """After outputs were computed and their sum was not finite: record the first
        non-finite output (name, value, time and, if one is the cause, the first non-finite
        input) for the next fmi2DoStep to refuse, and log it once. Without direct feedthrough
        every further step is refused (it comes from the state); with it, the next step goes
        on if finite inputs set meanwhile made the outputs finite."""
        msg = self._bad_output = self._nonfinite_output()
        if msg is None or msg == self._output_logged:
            return
        self._output_logged = msg
        if not self._feedthrough and self._output_error is None:
            self._output_error = msg
        self.log(f"{self._who()}: {msg}; the next step will be refused", Fmi2Status.error)

    def _refresh_outputs(self) -> None:
        """Compute the outputs and check them: one sum over the buffer (finite values sum to
        a finite number unless they overflow; an exact check only then)."""
        self.compute_outputs()
        self._dirty = False
        total = sum(self._out.tolist())
        if total - total != 0.0:               # some output is nan or +-inf (or overflow)
            self._check_outputs()
        elif self._bad_output is not None:
            self._bad_output = None

    def _nonfinite_output(self) -> str | None:
        """``output u[2] = inf at t = 0.04 s is not finite[: input y[1] = nan]`` for the
        first non-finite output (None if all are finite); t the current communication point."""
        bad = np.flatnonzero(~np.isfinite(self._out))
        if not bad.size:
            return None
        var = self.vars[self._vr_out + int(bad[0])]
        cause = self._first_bad_input()
        cause = f": {cause.removesuffix(' is not finite')}" if cause else ""
        t = self._t_next if self._t_next is not None else 0.0
        return f"output {var.name} = {self._out[bad[0]]} at t = {t} s is not finite{cause}"

    def _first_bad_parameter(self) -> str | None:
        """The first Real parameter element that is not finite, named with its value."""
        for spec in self.specs:
            if spec.causality != "parameter" or spec.type != "Real":
                continue
            arr = np.asarray(self.par[spec.name], float).reshape(-1)
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                name = element_names(spec.name, spec.shape)[int(bad[0])]
                return f"parameter {name} = {arr[bad[0]]} is not finite"
        return None

    def _nonfinite_step(self, t: float, h: float, state: np.ndarray) -> bool:
        """Report a step whose state became non-finite: name the outputs it reaches."""
        i = int(np.flatnonzero(~np.isfinite(state))[0])
        self.compute_outputs()
        self._dirty = False
        bad = np.flatnonzero(~np.isfinite(self._out))
        names = [self.vars[self._vr_out + int(j)].name for j in bad[:3]]
        where = (f"outputs {', '.join(names)}{' ...' if bad.size > 3 else ''}" if names
                 else f"internal state element {i + 1}")
        self._output_error = (f"{where} became non-finite in the step from t = {t} s to "
                              f"{t + h} s (state element {i + 1} = {state[i]})")
        self.log(f"{self._who()}: fmi2DoStep refused: {self._output_error}", Fmi2Status.error)
        return False
