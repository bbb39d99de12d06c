"""What the two estimator slaves share: est = estimate(mvec) on demand, q advanced per step.

A slave sets, in ``setup``, ``self.estimator`` (an
:class:`estimator_fmu.estimators.LinearEstimator`), ``self._mvec`` (the view of its input
buffer holding the measurement vector) and ``self._u`` (the applied input); its outputs are
the estimate, in the estimator's order.
"""
from __future__ import annotations

from fmu_common.native_form import BlockLayout, NativeForm, Role
from fmu_common.slave_base import DelegatedStateSlave

from .estimators import LinearEstimator

__all__ = ["EstimatorSlave"]


class EstimatorSlave(DelegatedStateSlave):
    """est[k] = Ce q[k] + Dm mvec[k] (direct feedthrough), q[k+1] = Aq est[k] + Bu u[k]."""

    step_parameter = "h"

    math_name = "estimator"
    evolving_name = "q"

    def native_form(self) -> NativeForm:
        """est = Ce q + Dm mvec (the measurement inputs), q+ = Aq est + Bu u.

        Raises
        ------
        NotImplementedError
            For the multi-rate filter of the navigation sensors (time-varying).
        """
        e = self.estimator
        if not isinstance(e, LinearEstimator):
            raise NotImplementedError(f"{type(self).__name__} with the multi-rate filter has "
                                      "no native (C) form")
        inputs, outputs = self.io_specs()
        u0 = BlockLayout(inputs)["u"].start
        return NativeForm(inputs=inputs, outputs=outputs, nq=e.q0.size, h=float(self.par["h"]),
                          description=self.description, roles=[
                              Role("C", "Ce", e.Ce, "estimate from the internal state: est = "
                                   "Ce q + Dm mvec"),
                              Role("D", "Dm", e.Dm, "estimate from the measurements (direct "
                                   "feedthrough)"),
                              Role("Bo", "Aq", e.Aq, "state update from the estimate: q+ = Aq "
                                   "est + Bu u"),
                              Role("B", "Bu", e.Bu, "state update from the applied input",
                                   col0=u0),
                              Role("q0", "q0", e.q0, "initial internal state"),
                          ])

    def compute_outputs(self) -> None:
        """est[k] = Ce q[k] + Dm mvec[k] into the output buffer."""
        self.estimator.estimate(self._mvec, out=self._out)

    def advance(self, step: float) -> None:
        """One sample period: q[k+1] = Aq est[k] + Bu u[k].

        Parameters
        ----------
        step : float
            The communication step, s (checked against h by the base class).
        """
        self.estimator.update(self._outputs_view(self._out), self._u)
